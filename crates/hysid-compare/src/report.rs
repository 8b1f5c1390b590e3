//! Writing a comparison: `report.md`, `report.json` and `models/*.json`.

use crate::Comparison;
use std::fmt::Write as _;
use std::path::Path;

/// A file name made from a run label.
fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    s.trim_matches('_').to_string()
}

/// Writes the report and the models into `dir` (created if needed); every
/// file is written atomically. Returns the paths written.
pub fn write_report(c: &mut Comparison, dir: &Path) -> std::io::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir.join("models"))?;
    let mut written = Vec::new();
    for r in &mut c.results {
        if let Some(m) = &r.model {
            let rel = format!("models/{}.json", slug(&r.name));
            let path = dir.join(&rel);
            hysid_core::atomic::write(&path, m.to_json().as_bytes())?;
            written.push(path);
            r.model_file = Some(rel);
        }
    }
    let json = serde_json::to_string_pretty(&*c).expect("report serialises") + "\n";
    let p = dir.join("report.json");
    hysid_core::atomic::write(&p, json.as_bytes())?;
    written.push(p);
    let p = dir.join("report.md");
    hysid_core::atomic::write(&p, markdown(c).as_bytes())?;
    written.push(p);
    Ok(written)
}

/// The report as Markdown.
pub fn markdown(c: &Comparison) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# {}\n", c.title);
    if !c.description.trim().is_empty() {
        let _ = writeln!(s, "{}\n", c.description.trim());
    }
    let _ = writeln!(
        s,
        "Data: {}. Validation scores leave out the first {} samples.\n",
        c.data, c.warmup
    );
    let _ = writeln!(
        s,
        "| run | method | na | nb | modes | fit_sim [%] | rmse_sim | fit_pred [%] | coverage | time [s] | note |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &c.results {
        let (fs, rs, fp, cov) = match &r.report {
            Some(v) => (
                format!("{:.2}", v.fit_sim),
                format!("{:.4}", v.rmse_sim),
                format!("{:.2}", v.fit_pred),
                format!("{:.3}", v.coverage),
            ),
            None => ("-".into(), "-".into(), "-".into(), "-".into()),
        };
        let mut note = r.error.clone().unwrap_or_default();
        if let Some(k) = r.report.as_ref().and_then(|v| v.diverged_at) {
            note = format!("simulation diverged at sample {k}");
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} |",
            r.name.replace('|', "/"),
            r.method,
            r.na,
            r.nb,
            r.modes.map_or("-".into(), |m| m.to_string()),
            fs,
            rs,
            fp,
            cov,
            r.seconds,
            note.replace('|', "/")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    #[test]
    fn slugs_are_file_names() {
        assert_eq!(super::slug("cluster [c=55]"), "cluster__c_55");
        assert_eq!(super::slug("arx(2,2)"), "arx_2_2");
    }
}

//! CSV input: a header row, then one sample per row; columns chosen by name.

use super::{DataError, RawTable};
use std::path::Path;

/// Reads the columns of `path` whose names are in `wanted` (others are only
/// checked for row length). Non-finite values, text in a numeric cell and
/// ragged rows are errors naming the row and the column.
pub(crate) fn read(path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    let file = std::fs::File::open(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_from(std::io::BufReader::new(file), path, wanted)
}

/// Same as [`read`] on any byte source; `path` only names it in errors.
pub(crate) fn read_from<R: std::io::Read>(
    source: R,
    path: &Path,
    wanted: &[&str],
) -> Result<RawTable, DataError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(source);
    let parse_err = |location: String, message: String| DataError::Parse {
        path: path.to_path_buf(),
        location,
        message,
    };
    let headers = rdr
        .headers()
        .map_err(|e| parse_err(String::new(), format!("cannot read the header row: {e}")))?
        .clone();
    if headers.is_empty() || headers.iter().all(str::is_empty) {
        return Err(parse_err(String::new(), "the header row is empty".into()));
    }
    let names: Vec<String> = headers.iter().map(str::to_string).collect();
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(parse_err(
                format!("column {}: ", i + 1),
                format!("column name '{n}' appears twice in the header"),
            ));
        }
    }
    let keep: Vec<usize> = (0..names.len())
        .filter(|&i| wanted.contains(&names[i].as_str()))
        .collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); keep.len()];
    for (r, rec) in rdr.records().enumerate() {
        let row = r + 1;
        let rec = rec.map_err(|e| parse_err(format!("row {row}: "), e.to_string()))?;
        if rec.len() != names.len() {
            return Err(parse_err(
                format!("row {row} (line {}): ", row + 1),
                format!("{} fields, the header has {}", rec.len(), names.len()),
            ));
        }
        for (slot, &c) in keep.iter().enumerate() {
            let cell = &rec[c];
            let loc = || format!("row {row} (line {}), column '{}': ", row + 1, names[c]);
            if cell.is_empty() {
                return Err(parse_err(loc(), "empty cell".into()));
            }
            let v: f64 = cell
                .parse()
                .map_err(|_| parse_err(loc(), format!("'{cell}' is not a number")))?;
            if !v.is_finite() {
                return Err(parse_err(loc(), format!("non-finite value '{cell}'")));
            }
            cols[slot].push(v);
        }
    }
    if cols.first().is_some_and(Vec::is_empty) || (keep.is_empty() && names.is_empty()) {
        return Err(parse_err(
            String::new(),
            "no data rows after the header".into(),
        ));
    }
    Ok(RawTable {
        path: path.to_path_buf(),
        what: "column",
        // Every header name is listed, so a missing column is reported with
        // what is there; unselected columns carry no data.
        columns: {
            let mut cols = cols.into_iter();
            names
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    (
                        n.clone(),
                        if keep.contains(&i) {
                            cols.next().unwrap_or_default()
                        } else {
                            Vec::new()
                        },
                    )
                })
                .collect()
        },
    })
}

#[cfg(test)]
mod tests {
    use crate::data::{DataError, DataSelection, load};
    use std::io::Write;

    fn csv(text: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
        f.write_all(text.as_bytes()).unwrap();
        f
    }

    fn err(text: &str) -> String {
        let f = csv(text);
        load(f.path(), &DataSelection::default())
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn reads_selected_columns_and_time() {
        let f = csv("t,u,y,junk\n0,1,2,a\n0.5,3,4,b\n1.0,5,6,c\n");
        let d = load(f.path(), &DataSelection::default()).unwrap();
        assert_eq!(d.u(0), &[1.0, 3.0, 5.0]);
        assert_eq!(d.y(), &[2.0, 4.0, 6.0]);
        assert_eq!(d.ts, Some(0.5));
    }

    #[test]
    fn errors_name_row_and_column() {
        let e = err("u,y\n1,2\n3,NaN\n");
        assert!(
            e.contains("row 2") && e.contains("column 'y'") && e.contains("non-finite"),
            "{e}"
        );
        let e = err("u,y\n1,2\n3,abc\n");
        assert!(
            e.contains("row 2") && e.contains("'abc' is not a number"),
            "{e}"
        );
        let e = err("u,y\n1,2\n3\n");
        assert!(e.contains("row 2") && e.contains("1 fields"), "{e}");
        let e = err("u,x\n1,2\n");
        assert!(
            e.contains("no column 'y'") && e.contains("available: u, x"),
            "{e}"
        );
        let e = err("u,y\n1,\n");
        assert!(e.contains("empty cell"), "{e}");
        let e = err("u,y\n");
        assert!(e.contains("no data rows"), "{e}");
    }

    #[test]
    fn decimation_and_rows() {
        let f = csv("u,y\n0,0\n1,1\n2,2\n3,3\n4,4\n5,5\n6,6\n");
        let sel = DataSelection {
            decimate: 2,
            rows: "1..3".parse().unwrap(),
            ..Default::default()
        };
        let d = load(f.path(), &sel).unwrap();
        assert_eq!(d.y(), &[2.0, 4.0]);
        let sel = DataSelection {
            rows: "9..".parse().unwrap(),
            ..Default::default()
        };
        assert!(matches!(load(f.path(), &sel), Err(DataError::Selection(_))));
    }
}

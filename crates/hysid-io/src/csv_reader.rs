//! CSV input: a header row, then one sample per row; columns chosen by name.

use super::{DataError, RawTable};
use std::path::Path;

/// Reads the columns of `path` whose names are in `wanted` (others are only
/// checked for row length). Non-finite values, text in a numeric cell and
/// ragged rows are errors naming the row and the column.
pub(crate) fn read(path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    let bytes = std::fs::read(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_from(&bytes, path, wanted)
}

/// The file line (1-based) on which a record starts. The csv crate's own
/// line count is off after blank lines and with CRLF endings; its byte
/// offset points at the blank lines skipped before the record.
fn line_of(bytes: &[u8], rec: &csv::StringRecord, fallback: usize) -> usize {
    let Some(start) = rec.position().map(|p| p.byte() as usize) else {
        return fallback;
    };
    let start = start.min(bytes.len());
    let skipped = bytes[start..]
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .count();
    1 + bytes[..start + skipped]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// Same as [`read`] on the file's bytes; `path` only names it in errors.
pub(crate) fn read_from(bytes: &[u8], path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(bytes);
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
    if let [only] = names.as_slice()
        && let Some(sep) = [';', '\t', '|'].into_iter().find(|&c| only.contains(c))
    {
        return Err(parse_err(
            String::new(),
            format!(
                "the header row '{}' is a single column: fields must be separated by commas, \
                 this file seems to use '{}'",
                only.escape_debug(),
                sep.escape_debug()
            ),
        ));
    }
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
        // Blank lines are skipped, so the file line comes from the reader.
        let line = line_of(bytes, &rec, row + 1);
        if rec.len() != names.len() {
            return Err(parse_err(
                format!("row {row} (line {line}): "),
                format!("{} fields, the header has {}", rec.len(), names.len()),
            ));
        }
        for (slot, &c) in keep.iter().enumerate() {
            let cell = &rec[c];
            let loc = || format!("row {row} (line {line}), column '{}': ", names[c]);
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
    use crate::load;
    use hysid_model::data::{DataError, DataSelection};
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
    fn line_numbers_count_blank_lines_and_crlf() {
        for (text, line) in [
            ("u,y\n1,2\n3,oops\n", 3),
            ("u,y\n1,2\n\n3,oops\n", 4),
            ("u,y\n1,2\n\n\n\n3,oops\n", 6),
            ("u,y\r\n1,2\r\n\r\n3,oops\r\n", 4),
            ("\u{feff}u,y\n1,2\n3,oops\n", 3),
        ] {
            let e = err(text);
            assert!(
                e.contains(&format!("row 2 (line {line}), column 'y'")),
                "{text:?}: {e}"
            );
        }
    }

    #[test]
    fn a_single_column_header_with_another_separator_is_named() {
        let e = err("u;y\n1;2\n");
        assert!(e.contains("'u;y'") && e.contains("';'"), "{e}");
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

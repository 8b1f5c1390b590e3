//! CSV input: a header row, then one sample per row; columns chosen by name.

use crate::table::{Available, RawTable};
use hysid_model::data::DataError;
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
/// offset points at the blank lines skipped before the record. This scans
/// the file up to the record, so it is only called to word an error.
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

/// The message of the csv crate's own error for a record that is not UTF-8
/// (what reading it as a `StringRecord` with `Trim::All` reports): `pos` is
/// the reader's position before the record, `raw` the record as read,
/// untrimmed, and `err` its validation error.
fn utf8_message(pos: &csv::Position, mut raw: csv::ByteRecord, err: &csv::Utf8Error) -> String {
    // The field and byte index are those of the ASCII-trimmed record.
    raw.trim();
    let trimmed = csv::StringRecord::from_byte_record(raw).err();
    let err = trimmed.as_ref().map_or(err, csv::FromUtf8Error::utf8_error);
    format!(
        "CSV parse error: record {} (line {}, field: {}, byte: {}): {err}",
        pos.record(),
        pos.line(),
        err.field(),
        pos.byte(),
    )
}

/// Same as [`read`] on the file's bytes; `path` only names it in errors.
pub(crate) fn read_from(bytes: &[u8], path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    read_rows(bytes, path, wanted, true)
}

/// [`read_from`]; with `plain`, the header row and the data rows are
/// first read as plain rows ([`plain_header`], [`plain_rows`]), else by
/// the csv crate alone.
fn read_rows(
    bytes: &[u8],
    path: &Path,
    wanted: &[&str],
    plain: bool,
) -> Result<RawTable, DataError> {
    // Only the header row is trimmed by the reader (its trimming allocates
    // twice per record); data cells are trimmed below, the kept ones only.
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::Headers)
        .from_reader(bytes);
    let parse_err = |location: String, message: String| DataError::Parse {
        path: path.to_path_buf(),
        location,
        message,
    };
    let header_error =
        |e: csv::Error| parse_err(String::new(), format!("cannot read the header row: {e}"));
    // The header as the csv crate reads it, when it is not plain.
    let headers: csv::StringRecord;
    let (names, start): (Vec<&str>, usize) = match plain.then(|| plain_header(bytes)).flatten() {
        Some(header) => header,
        None => {
            headers = rdr.headers().map_err(header_error)?.clone();
            let start =
                usize::try_from(rdr.position().byte()).map_or(bytes.len(), |b| b.min(bytes.len()));
            (headers.iter().collect(), start)
        }
    };
    if names.is_empty() || names.iter().all(|n| n.is_empty()) {
        return Err(parse_err(String::new(), "the header row is empty".into()));
    }
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
    let sorted = SortedNames::new(&names);
    if let Some(i) = sorted.first_repeat() {
        return Err(parse_err(
            format!("column {}: ", i + 1),
            format!("column name '{}' appears twice in the header", names[i]),
        ));
    }
    // The positions of the wanted names (each name appears once).
    let mut keep: Vec<usize> = wanted.iter().filter_map(|w| sorted.position(w)).collect();
    keep.sort_unstable();
    keep.dedup();
    let plain = plain
        .then(|| plain_rows(&bytes[start..], names.len(), &keep))
        .flatten();
    let cols = match plain {
        Some(cols) => cols,
        None => {
            // The header is read again by the reader when it was read as a
            // plain row, so that the positions it gives the rows are the
            // same.
            rdr.headers().map_err(header_error)?;
            // One record buffer for the whole file: read as bytes, then
            // checked to be UTF-8 in place (the same check `StringRecord`
            // reading makes).
            let mut cols: Vec<Vec<f64>> = vec![Vec::new(); keep.len()];
            let mut raw = csv::ByteRecord::new();
            let mut row = 0;
            loop {
                let pos = rdr.position().clone();
                let more = rdr
                    .read_byte_record(&mut raw)
                    .map_err(|e| parse_err(format!("row {}: ", row + 1), e.to_string()))?;
                if !more {
                    break;
                }
                row += 1;
                let rec =
                    csv::StringRecord::from_byte_record(std::mem::take(&mut raw)).map_err(|e| {
                        let err = e.utf8_error().clone();
                        parse_err(
                            format!("row {row}: "),
                            utf8_message(&pos, e.into_byte_record(), &err),
                        )
                    })?;
                // Blank lines are skipped, so the file line comes from the reader.
                let line = || line_of(bytes, &rec, row + 1);
                if rec.len() != names.len() {
                    return Err(parse_err(
                        format!("row {row} (line {}): ", line()),
                        format!("{} fields, the header has {}", rec.len(), names.len()),
                    ));
                }
                for (slot, &c) in keep.iter().enumerate() {
                    let cell = rec[c].trim();
                    let loc = || format!("row {row} (line {}), column '{}': ", line(), names[c]);
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
                raw = rec.into_byte_record();
            }
            cols
        }
    };
    if cols.first().is_some_and(Vec::is_empty) || (keep.is_empty() && names.is_empty()) {
        return Err(parse_err(
            String::new(),
            "no data rows after the header".into(),
        ));
    }
    Ok(RawTable {
        path: path.to_path_buf(),
        what: "column",
        columns: keep
            .iter()
            .zip(cols)
            .map(|(&c, values)| (names[c].to_string(), values))
            .collect(),
        available: Available::of(names.iter().copied()),
    })
}

/// The first line of `bytes` without its ending (`\n` or `\r\n`), as
/// text, when it is a plain row: no quote, no other `\r`, valid UTF-8.
/// The rest of `bytes` starts after the ending.
fn plain_line(bytes: &[u8]) -> Option<(&str, &[u8])> {
    let (mut line, rest) = match memchr::memchr(b'\n', bytes) {
        Some(i) => (&bytes[..i], &bytes[i + 1..]),
        None => (bytes, &bytes[bytes.len()..]),
    };
    if let [head @ .., b'\r'] = line {
        line = head;
    }
    if memchr::memchr2(b'"', b'\r', line).is_some() {
        return None;
    }
    Some((std::str::from_utf8(line).ok()?, rest))
}

/// The number of commas in `line`: on a long line by memchr's vectorised
/// count, whose call costs more than a plain loop on a short one.
fn commas(line: &[u8]) -> usize {
    if line.len() < 256 {
        line.iter().filter(|&&b| b == b',').count()
    } else {
        memchr::memchr_iter(b',', line).count()
    }
}

/// `field.trim()`, with the common case of nothing to trim told by its
/// first and last bytes: visible ASCII characters are no whitespace, and
/// a character of more than one byte neither starts nor ends with one.
fn trim(field: &str) -> &str {
    match field.as_bytes() {
        [first, .., last] if first.is_ascii_graphic() && last.is_ascii_graphic() => field,
        [only] if only.is_ascii_graphic() => field,
        _ => field.trim(),
    }
}

/// The names of the header row, trimmed, and the offset of the data rows
/// in `bytes`, when the header row is plain: a first line that is not
/// blank, not started by a byte-order mark, and a plain row
/// ([`plain_line`]). Such a header reads as it does through the csv crate
/// (trimmed as `Trim::Headers` trims it), without the crate storing and
/// trimming each field twice. `None` otherwise: the csv crate then reads
/// the header, and words any error.
fn plain_header(bytes: &[u8]) -> Option<(Vec<&str>, usize)> {
    if bytes.starts_with("\u{feff}".as_bytes()) {
        return None;
    }
    let (line, rest) = plain_line(bytes)?;
    if line.is_empty() {
        return None;
    }
    Some((names_of(line), bytes.len() - rest.len()))
}

/// The names of a plain header line: split at its commas, trimmed. Names
/// are short, so their commas are close together: a loop over the bytes
/// finds them faster than memchr's search, whose call costs more than the
/// few bytes it skips.
fn names_of(line: &str) -> Vec<&str> {
    let mut names = Vec::with_capacity(1 + commas(line.as_bytes()));
    let mut start = 0;
    for (i, b) in line.bytes().enumerate() {
        if b == b',' {
            names.push(trim(&line[start..i]));
            start = i + 1;
        }
    }
    names.push(trim(&line[start..]));
    names
}

/// The kept columns (`keep`, in order) of the data rows `data` when every
/// record is plain ([`plain_line`]; blank lines skipped, as the csv crate
/// skips them) with `width` fields separated by commas, and every kept
/// cell, trimmed, a finite number. Such records read as they do through
/// the csv crate, which stores the bounds of every field; here a row costs
/// a search for its end, its check, a count of its commas and a search
/// for its kept cells. `None` at the first record that is not plain: the
/// csv crate then reads the rows, and words any error.
fn plain_rows(data: &[u8], width: usize, keep: &[usize]) -> Option<Vec<Vec<f64>>> {
    let mut rest = data;
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); keep.len()];
    while !rest.is_empty() {
        let (line, next) = plain_line(rest)?;
        rest = next;
        if line.is_empty() {
            continue;
        }
        if 1 + commas(line.as_bytes()) != width {
            return None;
        }
        // The kept cells, up to the last one: cells of numbers are long
        // enough for memchr to find their commas faster than a byte loop.
        let mut kept = keep.iter().zip(cols.iter_mut()).peekable();
        let mut start = 0;
        for (field, end) in memchr::memchr_iter(b',', line.as_bytes())
            .chain([line.len()])
            .enumerate()
        {
            let Some((_, col)) = kept.next_if(|(k, _)| **k == field) else {
                if kept.peek().is_none() {
                    break;
                }
                start = end + 1;
                continue;
            };
            let v: f64 = line[start..end].trim().parse().ok()?;
            if !v.is_finite() {
                return None;
            }
            col.push(v);
            start = end + 1;
        }
    }
    Some(cols)
}

/// A header's names sorted so that equal names are neighbours (a hash
/// set would do, but sorting has no bad case): first by length and first
/// eight bytes, which tells most names apart with one integer comparison,
/// then by the whole name, then by position.
struct SortedNames<'a> {
    names: &'a [&'a str],
    /// `(key, position)` of every name, in order.
    order: Vec<((usize, u64), usize)>,
}

impl<'a> SortedNames<'a> {
    fn new(names: &'a [&'a str]) -> Self {
        let mut order: Vec<((usize, u64), usize)> = names
            .iter()
            .enumerate()
            .map(|(i, n)| (Self::key(n), i))
            .collect();
        order.sort_unstable_by(|(ka, a), (kb, b)| {
            ka.cmp(kb)
                .then_with(|| names[*a].cmp(names[*b]))
                .then(a.cmp(b))
        });
        SortedNames { names, order }
    }

    /// The length and the first eight bytes of `name`: equal names have
    /// equal keys (how names of different keys are ordered does not
    /// matter).
    fn key(name: &str) -> (usize, u64) {
        let head = name
            .bytes()
            .take(8)
            .fold(0u64, |k, b| (k << 8) | u64::from(b));
        (name.len(), head)
    }

    /// The position of the first name that repeats an earlier one.
    fn first_repeat(&self) -> Option<usize> {
        // In each run of equal names the second position is its first
        // repeat; names of different keys differ.
        self.order
            .windows(2)
            .filter(|w| w[0].0 == w[1].0 && self.names[w[0].1] == self.names[w[1].1])
            .map(|w| w[1].1)
            .min()
    }

    /// The first position of `name` among the names, if it is one.
    fn position(&self, name: &str) -> Option<usize> {
        let key = Self::key(name);
        let at = self
            .order
            .partition_point(|&(k, i)| (k, self.names[i]) < (key, name));
        self.order
            .get(at)
            .filter(|&&(k, i)| k == key && self.names[i] == name)
            .map(|&(_, i)| i)
    }
}

#[cfg(test)]
mod tests {
    use crate::{DataFormat, load, load_bytes};
    use hysid_model::data::{DataError, DataSelection};
    use std::io::Write;
    use std::path::Path;

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

    /// A time column's steps must all be the first one's (within 1 %): a
    /// missing sample is named by the row its step ends on, after
    /// decimation too; jitter within the tolerance passes.
    #[test]
    fn a_time_column_with_an_uneven_step_is_refused() {
        let e = err("t,u,y\n0,1,2\n0.5,3,4\n1.0,5,6\n2.0,7,8\n2.5,9,0\n");
        assert!(
            e.contains("column 't', row 4") && e.contains("time step 1 is not the first step 0.5"),
            "{e}"
        );
        let f = csv("t,u,y\n0,1,2\n1,3,4\n2,5,6\n3,7,8\n5,9,0\n6,1,1\n");
        let sel = DataSelection {
            decimate: 2,
            ..DataSelection::default()
        };
        let e = load(f.path(), &sel).unwrap_err().to_string();
        assert!(e.contains("column 't', row 5"), "{e}");
        let f = csv("t,u,y\n0,1,2\n0.5,3,4\n1.004,5,6\n1.5,7,8\n");
        assert_eq!(
            load(f.path(), &DataSelection::default()).unwrap().ts,
            Some(0.5)
        );
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
        assert!(matches!(
            load(f.path(), &sel),
            Err(DataError::Rows { beyond: false, .. })
        ));
    }

    /// The whole message, for inputs whose wording depends on how cells are
    /// trimmed and validated.
    fn message(bytes: &[u8]) -> String {
        load_bytes(
            bytes,
            DataFormat::Csv,
            Path::new("x.csv"),
            &DataSelection::default(),
        )
        .unwrap_err()
        .to_string()
    }

    #[test]
    fn exact_messages() {
        for (bytes, expected) in [
            (
                &b"u,y\n1,2\n3,  \xe94\n"[..],
                "x.csv: row 2: CSV parse error: record 2 (line 3, field: 1, byte: 8): \
                 invalid utf-8: invalid UTF-8 in field 1 near byte index 0",
            ),
            (
                b"u,y,z\n1,2,3\n3,4,\xc3\n\xa9\n",
                "x.csv: row 2: CSV parse error: record 2 (line 3, field: 2, byte: 12): \
                 invalid utf-8: invalid UTF-8 in field 2 near byte index 0",
            ),
            (
                b"u,y\n1,2\n\"3\n\",\" 4\"\n5,\"a\nb\"\n",
                "x.csv: row 3 (line 5), column 'y': 'a\nb' is not a number",
            ),
            (
                b"u,y\n  1 , 2 \n3,\t4\xc2\xa0\n5,6\xc2\xa0x\n",
                "x.csv: row 3 (line 4), column 'y': '6\u{a0}x' is not a number",
            ),
            (
                b" u , y \n1,2\n3,\xe2\x80\x83\n",
                "x.csv: row 2 (line 3), column 'y': empty cell",
            ),
            (
                b"u,y\n1,2\n3,4\n\"5,6\n",
                "x.csv: row 3 (line 4): 1 fields, the header has 2",
            ),
            (
                b"u,y\n1,2\n3,-infinity\n",
                "x.csv: row 2 (line 3), column 'y': non-finite value '-infinity'",
            ),
        ] {
            assert_eq!(
                message(bytes),
                expected,
                "{:?}",
                String::from_utf8_lossy(bytes)
            );
        }
    }

    #[test]
    fn a_file_of_200_000_columns_is_read_in_one_pass() {
        // 50 rows of 200 000 columns (20 MB), of which `u` and `y` are read.
        let columns = 200_000;
        let header: Vec<String> = (2..columns).map(|i| format!("c{i}")).collect();
        let header = format!("u,y,{}\n", header.join(","));
        let rest = ",0".repeat(columns - 2);
        let rows: String = (0..50).map(|k| format!("{k},{}{rest}\n", 2 * k)).collect();
        let d = load_bytes(
            format!("{header}{rows}").as_bytes(),
            DataFormat::Csv,
            Path::new("x.csv"),
            &DataSelection::default(),
        )
        .unwrap();
        assert_eq!(d.len(), 50);
        assert_eq!((d.u(0)[49], d.y()[49]), (49.0, 98.0));
        // A name repeated at the far end of the header is found.
        let twice = header.replace(&format!(",c{}\n", columns - 1), ",u\n");
        assert_eq!(
            message(format!("{twice}{rows}").as_bytes()),
            format!("x.csv: column {columns}: column name 'u' appears twice in the header")
        );
        // A missing column lists the first twenty names and counts the rest.
        let sel = DataSelection {
            output: "z".into(),
            ..DataSelection::default()
        };
        let e = load_bytes(
            format!("{header}{rows}").as_bytes(),
            DataFormat::Csv,
            Path::new("x.csv"),
            &sel,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            format!(
                "x.csv: no column 'z' (available: u, y, {}, and {} more)",
                (2..20)
                    .map(|i| format!("c{i}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                columns - 20
            )
        );
    }

    #[test]
    fn the_first_repeated_name_is_found_past_shared_prefixes() {
        use super::SortedNames;
        let first_repeat = |names: &[&str]| SortedNames::new(names).first_repeat();
        assert_eq!(first_repeat(&["u", "y", "t"]), None);
        // Same length and first eight bytes: told apart by the whole name.
        let names = ["aaaaaaaaX", "aaaaaaaaY", "b", "aaaaaaaaY", "aaaaaaaaX", "b"];
        assert_eq!(first_repeat(&names), Some(3));
        assert_eq!(first_repeat(&["", "x", ""]), Some(2));
    }

    #[test]
    fn names_are_found_by_their_sorted_order() {
        let names = ["aaaaaaaaX", "aaaaaaaaY", "b", "", "aaaaaaaaZ1", "c"];
        let sorted = super::SortedNames::new(&names);
        for (i, n) in names.iter().enumerate() {
            assert_eq!(sorted.position(n), Some(i), "{n}");
        }
        for n in ["aaaaaaaa", "aaaaaaaaW", "aaaaaaaaZ", "a", "d", " "] {
            assert_eq!(sorted.position(n), None, "{n}");
        }
    }

    /// Random files of plain and not so plain rows, under plain and not so
    /// plain headers: read as plain rows first (the fast path, falling back
    /// to the csv crate at the first record that is not plain), they give
    /// what the csv crate alone gives, the same columns or the same error.
    #[test]
    fn plain_rows_read_as_the_csv_crate_reads_them() {
        use proptest::prelude::*;
        let odd = prop::sample::select(vec![
            &b""[..],
            b"x",
            b"NaN",
            b"\"4\"",
            b"\"a,b\"",
            b"\xc3\xa9",
            b"\xff",
            b"7\r8",
        ]);
        let number = prop::sample::select(vec![&b"1"[..], b"-2.5", b" 3 ", b"1e3", b"\t5"]);
        let cell = prop_oneof![6 => number, 1 => odd];
        let end = prop::sample::select(vec![&b"\n"[..], b"\r\n", b"\r", b"", b"\n\n"]);
        let cells = |n| prop::collection::vec(cell.clone(), n);
        // Rows as wide as the header (three columns), mostly.
        let row =
            (prop_oneof![6 => cells(3..4), 1 => cells(1..5)], end).prop_map(|(cells, end)| {
                let mut row = cells.join(&b","[..]);
                row.extend_from_slice(end);
                row
            });
        let file = (
            prop::sample::select(vec![
                "t,u,y\n",
                "u,y,z\r\n",
                "y, u ,x\n",
                "u,t,t2\n",
                "\u{feff}u,y,t\n",
                "\"u\",y,t\n",
                "\nu,y,t\n",
                "u,y\rt\n",
                "u,\u{a0}y\u{2003},t\r\n",
            ]),
            prop::collection::vec(row, 0..6),
        )
            .prop_map(|(header, rows)| [header.as_bytes().to_vec(), rows.concat()].concat());
        let outcome = |bytes: &[u8], plain: bool| match super::read_rows(
            bytes,
            Path::new("x.csv"),
            &["u", "y", "t"],
            plain,
        ) {
            Ok(t) => Ok((t.columns, t.available.to_string())),
            Err(e) => Err(e.to_string()),
        };
        let read = std::cell::Cell::new(0);
        proptest!(ProptestConfig::with_cases(2000), |(bytes in file)| {
            let plain = outcome(&bytes, true);
            read.set(read.get() + usize::from(plain.is_ok()));
            prop_assert_eq!(plain, outcome(&bytes, false), "{:?}", String::from_utf8_lossy(&bytes));
        });
        // About a fifth of the files read (the rest end in an error).
        assert!(read.get() >= 200, "{} of 2000 files read", read.get());
    }

    /// A file of `rows` data rows with blank lines (also just before row
    /// `bad`), CRLF endings and quoted cells spanning lines, whose row `bad`
    /// holds `bad_row`; returns the text and the file line on which row
    /// `bad` starts.
    fn long_file(rows: usize, bad: usize, bad_row: &str) -> (String, usize) {
        let mut text = String::from("t,note,u,y\n");
        let mut line = 2;
        let mut bad_line = 0;
        for r in 1..=rows {
            if r.is_multiple_of(997) || r == bad {
                text.push_str(if r % 3 == 1 { "\r\n\r\n" } else { "\n\n" });
                line += 2;
            }
            let row = if r == bad {
                bad_line = line;
                bad_row.to_string()
            } else if r.is_multiple_of(13) {
                format!("{r},\"two\nlines, quoted\",{},-{}", r % 7, r % 5)
            } else {
                format!("{r},,{}.5,{}e-3", r % 7, r % 11)
            };
            text.push_str(&row);
            text.push_str(if r.is_multiple_of(3) { "\r\n" } else { "\n" });
            line += 1 + row.matches('\n').count();
        }
        (text, bad_line)
    }

    #[test]
    fn line_numbers_stay_right_deep_into_a_long_file() {
        let (text, line) = long_file(60_000, 50_000, "50000,\"a\nb\",1,oops");
        // Blank lines and the quoted newlines before row 50 000 put it well
        // past line 50 001.
        assert!(line > 50_001 + 3_000, "{line}");
        assert_eq!(
            message(text.as_bytes()),
            format!("x.csv: row 50000 (line {line}), column 'y': 'oops' is not a number")
        );
        // Here the rows end in CRLF, and so do the blank lines before it.
        let (text, line) = long_file(60_000, 49_999, "49999,x,1");
        assert_eq!(
            message(text.as_bytes()),
            format!("x.csv: row 49999 (line {line}): 3 fields, the header has 4")
        );
        let (text, _) = long_file(60_000, 0, "");
        let d = load_bytes(
            text.as_bytes(),
            DataFormat::Csv,
            Path::new("x.csv"),
            &DataSelection::default(),
        )
        .unwrap();
        assert_eq!(d.len(), 60_000);
        assert_eq!(d.u(0)[12], 6.0);
        assert_eq!(d.y()[12], -3.0);
        assert_eq!(d.y()[59_999], 6e-3);
        assert_eq!(d.ts, Some(1.0));
    }
}

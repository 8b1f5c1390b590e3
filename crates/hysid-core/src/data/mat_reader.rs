//! MATLAB level-5 MAT-file input (compressed or not), through the pure-Rust
//! `matrw` crate. Variables are chosen by name, like CSV columns.

use super::{DataError, RawTable};
use matrw::MatVariable;
use std::path::Path;

/// Reads the variables of `path` named in `wanted` that exist in the file.
/// Each must be a real numeric vector (N x 1 or 1 x N).
pub(crate) fn read(path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    let bytes = std::fs::read(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_bytes(&bytes, path, wanted)
}

/// Same as [`read`] on the file's bytes; `path` only names it in errors.
pub(crate) fn read_bytes(
    bytes: &[u8],
    path: &Path,
    wanted: &[&str],
) -> Result<RawTable, DataError> {
    let perr = |location: String, message: String| DataError::Parse {
        path: path.to_path_buf(),
        location,
        message,
    };
    if bytes.len() < 128 {
        return Err(perr(
            String::new(),
            "too short for a MAT-file header (128 bytes)".into(),
        ));
    }
    // matrw trusts the sizes written in the file and reserves them before
    // reading (a 211-byte file found by fuzzing asked for 3.9 GB): check
    // that every element fits inside its parent first.
    let little_endian = &bytes[126..128] != b"MI";
    check_elements(&bytes[128..], 128, little_endian, 0).map_err(|m| {
        perr(
            String::new(),
            format!("not a readable level-5 MAT-file: {m}"),
        )
    })?;
    // matrw is a third-party parser: a malformed file must still end in an
    // error, never in a crash of the caller.
    let parsed = guarded(|| matrw::load_matfile_from_u8(bytes))
        .ok_or_else(|| perr(String::new(), "not a readable level-5 MAT-file".into()))?
        .map_err(|e| {
            perr(
                String::new(),
                format!("not a readable level-5 MAT-file: {}", plain(&e.to_string())),
            )
        })?;
    let mut columns = Vec::new();
    let available: Vec<String> = parsed.iter().map(|(k, _)| k.clone()).collect();
    for (name, var) in parsed.iter() {
        if !wanted.contains(&name.as_str()) {
            continue;
        }
        let loc = format!("variable '{name}': ");
        let unreadable = || perr(loc.clone(), "cannot be read (malformed variable)".into());
        let dim = guarded(|| var.dim()).ok_or_else(unreadable)?;
        if dim.iter().filter(|&&d| d != 1).count() > 1 {
            return Err(perr(
                loc,
                format!("is {dims}, expected a vector", dims = dims(&dim)),
            ));
        }
        // At most one dimension differs from 1, so the product cannot overflow.
        let n: usize = dim.iter().product();
        if guarded(|| var.is_complex()).ok_or_else(unreadable)? == Some(true) {
            return Err(perr(loc, "is complex, expected real values".into()));
        }
        let values = guarded(|| to_f64(var))
            .ok_or_else(unreadable)?
            .ok_or_else(|| perr(loc.clone(), "is not a numeric array".into()))?;
        if values.len() != n {
            return Err(perr(
                loc,
                "data length does not match its dimensions".into(),
            ));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(perr(
                format!("variable '{name}', row {}: ", k + 1),
                format!("non-finite value {}", values[k]),
            ));
        }
        columns.push((name.clone(), values));
    }
    if columns.is_empty() && available.is_empty() {
        return Err(perr(String::new(), "holds no variable".into()));
    }
    // Keep the names of every variable so that a missing one is reported with
    // what is there; unselected ones carry no data.
    for name in available {
        if !columns.iter().any(|(n, _)| *n == name) {
            columns.push((name, Vec::new()));
        }
    }
    Ok(RawTable {
        path: path.to_path_buf(),
        what: "variable",
        columns,
    })
}

/// Nesting depth of miMATRIX elements (cells and structures) checked.
const MAX_DEPTH: usize = 16;
/// Largest inflated miCOMPRESSED element accepted (4 GiB).
const MAX_INFLATED: u64 = 1 << 32;

/// Walks the data elements of a level-5 MAT-file ("MAT-File Format",
/// MathWorks, ch. 1: an 8-byte tag with type and byte count, or a small
/// element packing both in 4 bytes) and checks that every declared size
/// fits inside its parent: the file, an miMATRIX element, or the inflated
/// content of an miCOMPRESSED element. `base` is the offset of `buf` in the
/// file, for the message.
fn check_elements(buf: &[u8], base: usize, le: bool, depth: usize) -> Result<(), String> {
    const MI_MATRIX: u32 = 14;
    const MI_COMPRESSED: u32 = 15;
    let word = |at: usize| -> u32 {
        let b = [buf[at], buf[at + 1], buf[at + 2], buf[at + 3]];
        if le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        }
    };
    let mut pos = 0;
    while pos < buf.len() {
        let rest = buf.len() - pos;
        if rest < 8 {
            // Padding at the end of a parent is fine; a cut tag is not.
            if depth > 0 && buf[pos..].iter().all(|&b| b == 0) {
                return Ok(());
            }
            return Err(format!(
                "the element at byte {} is cut ({rest} bytes left, a tag has 8)",
                base + pos
            ));
        }
        // matrw reads the type of a variable from its low byte only: a tag
        // 0x2f0f is compressed to it. Judge the kind the same way.
        let ty = word(pos);
        let kind = ty & 0xff;
        if ty >> 16 != 0 && kind != MI_MATRIX && kind != MI_COMPRESSED {
            // Small data element: type and size in 4 bytes, data in the next 4.
            pos += 8;
            continue;
        }
        let n = word(pos + 4) as usize;
        let start = pos + 8;
        if n > buf.len() - start {
            return Err(format!(
                "the element at byte {} declares {n} bytes, only {} remain (truncated or corrupted file)",
                base + pos,
                buf.len() - start
            ));
        }
        let body = &buf[start..start + n];
        match kind {
            MI_MATRIX if depth < MAX_DEPTH => {
                // matrw reads an array's sub-elements one after the other
                // without bounding them by the array's own size: check the
                // first five (flags, dimensions, name, data) against all
                // that follows, too.
                check_sequence(&buf[start..], base + start, le, 5)?;
                check_elements(body, base + start, le, depth + 1)?
            }
            MI_COMPRESSED if depth == 0 => {
                use std::io::Read;
                let mut inflated = Vec::new();
                flate2::read::ZlibDecoder::new(body)
                    .take(MAX_INFLATED)
                    .read_to_end(&mut inflated)
                    .map_err(|e| {
                        format!(
                            "the compressed element at byte {} does not inflate: {e}",
                            base + pos
                        )
                    })?;
                check_elements(&inflated, 0, le, depth + 1).map_err(|e| {
                    format!("in the compressed element at byte {}: {e}", base + pos)
                })?;
            }
            _ => {}
        }
        pos = start + n;
        if kind != MI_COMPRESSED {
            pos = pos.next_multiple_of(8).min(buf.len());
        }
    }
    Ok(())
}

/// The first `count` element tags of `buf`, each checked to fit in what
/// follows it (see [`check_elements`]).
fn check_sequence(buf: &[u8], base: usize, le: bool, count: usize) -> Result<(), String> {
    let word = |at: usize| -> u32 {
        let b = [buf[at], buf[at + 1], buf[at + 2], buf[at + 3]];
        if le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        }
    };
    let mut pos = 0;
    for _ in 0..count {
        if buf.len() - pos < 8 {
            return Ok(());
        }
        if word(pos) >> 16 != 0 {
            pos += 8;
            continue;
        }
        let n = word(pos + 4) as usize;
        let left = buf.len() - pos - 8;
        if n > left {
            return Err(format!(
                "the element at byte {} declares {n} bytes, only {left} remain (truncated or corrupted file)",
                base + pos
            ));
        }
        pos = (pos + 8 + n).next_multiple_of(8).min(buf.len());
    }
    Ok(())
}

thread_local! {
    static IN_GUARDED_PARSER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// True while the current thread runs third-party parser code whose panics
/// the MAT reader catches and turns into a [`DataError`]. A program's panic
/// hook can stay silent then (the `hysid` CLI does), so that a malformed
/// file gives one error line, not a panic report followed by it.
pub fn inside_guarded_parser() -> bool {
    IN_GUARDED_PARSER.with(std::cell::Cell::get)
}

/// Runs `f` (matrw code), `None` if it panicked.
fn guarded<T>(f: impl FnOnce() -> T) -> Option<T> {
    struct Reset(bool);
    impl Drop for Reset {
        fn drop(&mut self) {
            IN_GUARDED_PARSER.with(|g| g.set(self.0));
        }
    }
    let _reset = Reset(IN_GUARDED_PARSER.with(|g| g.replace(true)));
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).ok()
}

/// matrw's errors come from binrw with terminal colours, box-drawing rules
/// and a backtrace of the parser's source files; keep the words only
/// ("no variants matched at 0x0 While parsing field 'matfile_ver' in
/// MatFileHeader").
fn plain(message: &str) -> String {
    let mut text = String::with_capacity(message.len());
    let mut chars = message.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            // An ANSI escape sequence: ESC [ parameters final-letter.
            if chars.peek() == Some(&'[') {
                chars.next();
                for c in chars.by_ref() {
                    if c.is_ascii_alphabetic() {
                        break;
                    }
                }
            }
            continue;
        }
        if ('\u{2500}'..='\u{257f}').contains(&c) || c.is_control() {
            text.push(' ');
        } else {
            text.push(c);
        }
    }
    let words: Vec<&str> = text
        .split_whitespace()
        .filter(|w| !matches!(*w, "Backtrace" | "binrw" | "error" | "0:" | "Error:"))
        .collect();
    // Drop the parser's own source locations (" at /.../header.rs:87").
    let mut kept = Vec::with_capacity(words.len());
    let mut i = 0;
    while i < words.len() {
        if words[i] == "at" && words.get(i + 1).is_some_and(|w| w.contains(".rs:")) {
            i += 2;
            continue;
        }
        kept.push(words[i]);
        i += 1;
    }
    // binrw lists every variant it tried ("... ObjectMCOS no variants
    // matched ..."): the first clause says where the file stops making sense.
    const MAX_WORDS: usize = 16;
    let mut first = Vec::new();
    for w in kept {
        if let Some(w) = w.strip_suffix("...") {
            first.push(w);
            break;
        }
        first.push(w);
        if first.len() == MAX_WORDS {
            break;
        }
    }
    if first.is_empty() {
        "malformed file".into()
    } else {
        first.join(" ")
    }
}

fn dims(d: &[usize]) -> String {
    d.iter().map(usize::to_string).collect::<Vec<_>>().join("x")
}

fn widen<T: Into<f64>>(v: Option<Vec<T>>) -> Option<Vec<f64>> {
    v.map(|x| x.into_iter().map(Into::into).collect())
}

/// Any real numeric class, widened to f64.
fn to_f64(v: &MatVariable) -> Option<Vec<f64>> {
    v.to_vec_f64()
        .or_else(|| widen(v.to_vec_f32()))
        .or_else(|| widen(v.to_vec_i32()))
        .or_else(|| widen(v.to_vec_i16()))
        .or_else(|| widen(v.to_vec_i8()))
        .or_else(|| widen(v.to_vec_u8()))
        .or_else(|| widen(v.to_vec_u16()))
        .or_else(|| widen(v.to_vec_u32()))
}

#[cfg(test)]
mod tests {
    use crate::data::{DataSelection, load};
    use matrw::{MatFile, matvar};

    fn write(compress: bool, y: Vec<f64>) -> tempfile::TempPath {
        let path = tempfile::Builder::new()
            .suffix(".mat")
            .tempfile()
            .unwrap()
            .into_temp_path();
        let mut m = MatFile::new();
        m.insert("u", matvar!(vec![1.0, 2.0, 3.0]));
        m.insert("y", matvar!(y));
        matrw::save_matfile_v7(path.to_str().unwrap(), m, compress).unwrap();
        path
    }

    #[test]
    fn reads_compressed_and_uncompressed() {
        for compress in [false, true] {
            let p = write(compress, vec![4.0, 5.0, 6.0]);
            let d = load(&p, &DataSelection::default()).unwrap();
            assert_eq!(d.y(), &[4.0, 5.0, 6.0]);
            assert_eq!(d.u(0), &[1.0, 2.0, 3.0]);
            assert_eq!(d.ts, None);
        }
    }

    #[test]
    fn missing_variable_and_non_finite_are_named() {
        let p = write(false, vec![4.0, f64::INFINITY, 6.0]);
        let e = load(&p, &DataSelection::default()).unwrap_err().to_string();
        assert!(
            e.contains("variable 'y', row 2") && e.contains("non-finite"),
            "{e}"
        );
        let sel = DataSelection {
            output: "z".into(),
            ..Default::default()
        };
        let p = write(false, vec![4.0, 5.0, 6.0]);
        let e = load(&p, &sel).unwrap_err().to_string();
        assert!(e.contains("no variable 'z'") && e.contains("u"), "{e}");
    }

    #[test]
    fn parser_errors_are_plain_words() {
        let raw = "binrw error\n\u{1b}[1m\u{2578}\u{2501}\u{2505} Backtrace \u{2505}\n 0: \u{1b}[1mError: no variants matched at 0x0\u{1b}[22m\n \u{1b}[1mWhile parsing field 'matfile_ver' in MatFileHeader\u{1b}[22m at /root/.cargo/registry/src/matrw-0.1.4/src/parser/header.rs:87\n\u{2578}\u{2501}";
        assert_eq!(
            super::plain(raw),
            "no variants matched at 0x0 While parsing field 'matfile_ver' in MatFileHeader"
        );
        assert_eq!(super::plain("\u{1b}[1m\u{2501}"), "malformed file");
        let tried_everything = "no variants matched at 0xb8... ObjectMCOS no variants matched at 0xb8 Unexpected value for enum: 0 1: While parsing field 'data_type'";
        assert_eq!(
            super::plain(tried_everything),
            "no variants matched at 0xb8"
        );
    }

    #[test]
    fn fuzzer_crash_inputs_are_errors() {
        // A dimension product that overflows inside matrw (fuzz target
        // mat_reader; the first byte chose the selection there).
        let bytes = include_bytes!("../../../../tests/data/fuzz/mat_reader-mul-overflow-4ed3ecb8");
        let e = crate::data::load_bytes(
            &bytes[1..],
            crate::data::DataFormat::Mat,
            std::path::Path::new("crash.mat"),
            &DataSelection::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("crash.mat: not a readable level-5 MAT-file"),
            "{e}"
        );
        assert!(!crate::data::inside_guarded_parser());
    }

    #[test]
    fn sizes_beyond_the_parent_are_refused_before_matrw_allocates() {
        // A 211-byte file whose array-name element declares ~4 GB (fuzz
        // target mat_reader, libFuzzer out-of-memory).
        // A 649-byte one whose compressed array's data element asks for
        // 3.3 GB, beyond what the array itself declares.
        for bytes in [
            &include_bytes!("../../../../tests/data/fuzz/mat_reader-oom-33af7a43")[..],
            &include_bytes!("../../../../tests/data/fuzz/mat_reader-oom-a139648a")[..],
        ] {
            let e = crate::data::load_bytes(
                &bytes[1..],
                crate::data::DataFormat::Mat,
                std::path::Path::new("oom.mat"),
                &DataSelection::default(),
            )
            .unwrap_err()
            .to_string();
            assert!(
                e.contains("declares") && e.contains("remain") || e.contains("does not inflate"),
                "{e}"
            );
        }
        // The real record and matrw's own files pass the check.
        for compress in [false, true] {
            let p = write(compress, vec![4.0, 5.0, 6.0]);
            let b = std::fs::read(&p).unwrap();
            super::check_elements(&b[128..], 128, true, 0).unwrap();
        }
    }

    #[test]
    fn garbage_is_an_error_not_a_crash() {
        let mut bytes = vec![0u8; 300];
        bytes[..6].copy_from_slice(b"MATLAB");
        let path = tempfile::Builder::new()
            .suffix(".mat")
            .tempfile()
            .unwrap()
            .into_temp_path();
        std::fs::write(&path, &bytes).unwrap();
        assert!(load(&path, &DataSelection::default()).is_err());
        std::fs::write(&path, b"short").unwrap();
        assert!(load(&path, &DataSelection::default()).is_err());
    }
}

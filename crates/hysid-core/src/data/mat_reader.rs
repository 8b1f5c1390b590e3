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
    // matrw is a third-party parser: a malformed file must still end in an
    // error, never in a crash of the caller.
    let parsed = std::panic::catch_unwind(|| matrw::load_matfile_from_u8(bytes))
        .map_err(|_| perr(String::new(), "not a readable level-5 MAT-file".into()))?
        .map_err(|e| {
            perr(
                String::new(),
                format!("not a readable level-5 MAT-file: {e}"),
            )
        })?;
    let mut columns = Vec::new();
    let available: Vec<String> = parsed.iter().map(|(k, _)| k.clone()).collect();
    for (name, var) in parsed.iter() {
        if !wanted.contains(&name.as_str()) {
            continue;
        }
        let loc = format!("variable '{name}': ");
        let dim = var.dim();
        let n: usize = dim.iter().product();
        if dim.iter().filter(|&&d| d != 1).count() > 1 {
            return Err(perr(
                loc,
                format!("is {dims}, expected a vector", dims = dims(&dim)),
            ));
        }
        if var.is_complex() == Some(true) {
            return Err(perr(loc, "is complex, expected real values".into()));
        }
        let values =
            to_f64(var).ok_or_else(|| perr(loc.clone(), "is not a numeric array".into()))?;
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

fn dims(d: &[usize]) -> String {
    d.iter().map(usize::to_string).collect::<Vec<_>>().join("x")
}

/// Any real numeric class, widened to f64.
fn to_f64(v: &MatVariable) -> Option<Vec<f64>> {
    v.to_vec_f64()
        .or_else(|| {
            v.to_vec_f32()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_i32()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_i16()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_i8()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_u8()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_u16()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
        .or_else(|| {
            v.to_vec_u32()
                .map(|x| x.into_iter().map(f64::from).collect())
        })
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

//! MAT-files as users have them: written by `scipy.io.savemat` (compressed
//! or not, row or column vectors, float64, float32 and int16) and with the
//! header MATLAB writes, each read to exactly the signals of its CSV twin;
//! level-4 and HDF5-based (v7.3) files named for what they are, and a
//! file of another format under a MAT-file name as none of them. The
//! fixtures and their generator are in `tests/data/mat/`.

use hysid_model::data::{DataError, DataSelection};
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/mat")
        .join(name)
}

#[test]
fn files_from_scipy_and_matlab_read_as_their_csv_twins() {
    let sel = DataSelection::default();
    for stem in [
        "scipy_f64_col_compressed",
        "scipy_f64_row",
        "scipy_f32_col",
        "scipy_i16_row_compressed",
        "matlab_header",
    ] {
        let mat = hysid_io::load(&fixture(&format!("{stem}.mat")), &sel)
            .unwrap_or_else(|e| panic!("{stem}.mat: {e}"));
        let csv = hysid_io::load(&fixture(&format!("{stem}.csv")), &sel).unwrap();
        assert_eq!(mat.len(), 200, "{stem}");
        assert_eq!(mat.u(0), csv.u(0), "{stem}: u");
        assert_eq!(mat.y(), csv.y(), "{stem}: y");
    }
}

#[test]
fn level4_and_hdf5_files_are_named_for_what_they_are() {
    let sel = DataSelection::default();
    for (file, says) in [
        ("level4.mat", "a level-4 MAT-file"),
        (
            "v73_header.mat",
            "an HDF5-based MAT-file (MATLAB save -v7.3)",
        ),
    ] {
        let e = hysid_io::load(&fixture(file), &sel).unwrap_err();
        assert!(matches!(e, DataError::Parse { .. }), "{file}: {e:?}");
        let text = e.to_string();
        assert!(text.contains(says) && text.contains(file), "{file}: {text}");
        assert!(text.contains("save it as level 5"), "{text}");
    }
}

/// A CSV file renamed `.mat` is not taken for a level-4 file.
#[test]
fn another_format_under_a_mat_name_is_not_a_mat_file() {
    let dir = tempfile::tempdir().unwrap();
    let csv = std::fs::read(fixture("scipy_f64_row.csv")).unwrap();
    let file = dir.path().join("renamed.mat");
    std::fs::write(&file, csv).unwrap();
    let e = hysid_io::load(&file, &DataSelection::default()).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("renamed.mat") && text.contains("not a MAT-file"),
        "{text}"
    );
    assert!(!text.contains("level-4 MAT-file ("), "{text}");
}

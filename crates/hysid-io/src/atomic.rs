//! Atomic file output: write to a temporary file beside the target, then
//! rename it into place. A failure leaves no partial file and never
//! overwrites a good one.

use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically. A missing folder and a `path`
/// that is a folder are errors that say so (not an error about the
/// temporary file).
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("the folder {} does not exist", dir.display()),
        ));
    }
    if path.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "it is a folder; give a file name",
        ));
    }
    let mut tmp = tempfile::Builder::new()
        .prefix(".hysid-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    // tempfile creates files private (0600); output files are ordinary ones.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        super::write(&p, b"one").unwrap();
        super::write(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(
                std::fs::metadata(&p).unwrap().permissions().mode() & 0o777,
                0o644
            );
        }
        let e = super::write(&dir.path().join("no/such/dir/m.json"), b"x").unwrap_err();
        assert!(e.to_string().contains("no/such/dir does not exist"), "{e}");
        let e = super::write(dir.path(), b"x").unwrap_err();
        assert_eq!(e.to_string(), "it is a folder; give a file name");
    }
}

//! Atomic file output: write to a temporary file beside the target, then
//! rename it into place. A failure leaves no partial file and never
//! overwrites a good one. A symbolic link is written through (its target
//! is replaced, the link stays); a target that is not a regular file (a
//! device such as `/dev/null`, a pipe) is written directly, since renaming
//! over it would replace the device with a file.

use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically. A missing folder and a `path`
/// that is a folder are errors that say so (not an error about the
/// temporary file).
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
        && !meta.is_dir()
    {
        return std::fs::OpenOptions::new()
            .write(true)
            .open(path)?
            .write_all(bytes);
    }
    let resolved = std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.file_type().is_symlink())
        .then(|| std::fs::canonicalize(path).ok())
        .flatten();
    let path = resolved.as_deref().unwrap_or(path);
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
    // The temporary's own name means nothing to the user: the error names
    // the folder.
    let mut tmp = tempfile::Builder::new()
        .prefix(".hysid-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| {
            let kind = e.kind();
            std::io::Error::new(
                kind,
                format!("the folder {} cannot be written: {kind}", dir.display()),
            )
        })?;
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

    /// A link is written through, and a pipe (as a device would be) is
    /// written into, not replaced by a file.
    #[cfg(unix)]
    #[test]
    fn links_and_special_files_stay_what_they_are() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("model.json");
        std::fs::write(&target, b"old").unwrap();
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        super::write(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&target).unwrap(), b"new");

        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            return; // no mkfifo on this system
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        super::write(&fifo, b"through the pipe").unwrap();
        // Checked before waiting for the reader, which a pipe replaced by
        // a file would leave waiting.
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(reader.join().unwrap(), b"through the pipe");
    }
}

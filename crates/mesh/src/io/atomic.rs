//! Atomic file writing: write a temporary file next to the target, then rename it onto the target.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use crate::MeshError;

/// Write `path` atomically: `write` fills a buffered temporary file created in the target's directory
/// (so that the final rename stays on one file system); the buffer is flushed, the file synced to disk,
/// and only then renamed onto `path`. Readers see either the old file or the complete new one, never a
/// partial file.
///
/// On any error (from `write`, the flush, the sync or the rename) the temporary file is removed and the
/// target is left untouched. If the target exists, the new file gets its permissions; otherwise the
/// usual ones for a new file (`0o666` less the umask on Unix, not the `0o600` of a bare temporary file).
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use std::io::Write;
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("summary.json");
/// hooke_mesh::io::write_atomically(&path, |out| writeln!(out, "{{\"frames\": 10}}"))?;
/// assert_eq!(std::fs::read_to_string(&path)?, "{\"frames\": 10}\n");
/// # Ok(())
/// # }
/// ```
///
/// # Errors
/// [`MeshError::Io`] naming `path`, with the underlying error: the directory is missing or not
/// writable, `write` failed, or the disk is full.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), MeshError> {
    write_inner(path, write).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_inner(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let directory = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path.file_name().ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path has no file name",
        )
    })?;
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(name);
    prefix.push(".");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let temporary = builder.tempfile_in(directory)?;
    if let Ok(metadata) = std::fs::metadata(path) {
        // Keep the permissions of the file being replaced. Failure here is not worth failing the write.
        let _ = temporary.as_file().set_permissions(metadata.permissions());
    }
    // From here on, dropping `temp_path` (on any early return) deletes the temporary file.
    let (file, temp_path) = temporary.into_parts();
    let mut out = BufWriter::new(file);
    write(&mut out)?;
    out.flush()?;
    let file = out.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()?;
    drop(file);
    temp_path.persist(path).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomically(&path, |out| out.write_all(b"one")).unwrap();
        write_atomically(&path, |out| out.write_all(b"two")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(entries(dir.path()), vec!["a.txt"]);
    }

    #[test]
    fn failure_leaves_target_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, b"old").unwrap();
        let e = write_atomically(&path, |out| {
            out.write_all(&[b'x'; 100_000])?;
            Err(std::io::Error::other("simulated failure"))
        })
        .unwrap_err();
        assert!(matches!(e, MeshError::Io { .. }));
        assert!(e.to_string().contains("a.txt") && e.to_string().contains("simulated"));
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["a.txt"]);
    }

    #[test]
    fn missing_directory_is_an_io_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing").join("a.txt");
        let e = write_atomically(&path, |out| out.write_all(b"x")).unwrap_err();
        assert!(matches!(e, MeshError::Io { .. }), "{e:?}");
    }

    #[cfg(unix)]
    #[test]
    fn new_files_are_not_private() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomically(&path, |out| out.write_all(b"x")).unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        // Owner read/write at least; and more than the 0o600 of a bare temporary file unless the umask
        // forbids it (then the mode equals 0o666 less the umask, which we cannot read portably).
        assert_eq!(mode & 0o600, 0o600);
    }
}

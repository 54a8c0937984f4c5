//! Atomic file writing: write a temporary file next to the target, then rename it onto the target.
//!
//! This is the workspace's one implementation: the command's frames, summaries, checkpoints,
//! previews and benchmark files, and the editor's frames and scene files, are all written here.
//!
//! A temporary file is named `.{target file name}.{six random letters or digits}.tmp`, in the
//! target's directory: each writer has its own (two writers of the same target never share one),
//! and a file that a killed process left behind is recognisable by its name alone, so that the next
//! run can remove it ([`remove_temporaries`], [`remove_temporaries_of`], [`is_temporary`]).

use std::ffi::OsStr;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use crate::MeshError;

/// How a temporary file's name ends.
const SUFFIX: &str = ".tmp";

/// How many random letters and digits a temporary file's name holds (tempfile's alphabet).
const RANDOM_CHARS: usize = 6;

/// Write `path` atomically: `write` fills a buffered temporary file created in the target's directory
/// (so that the final rename stays on one file system); the buffer is flushed, the file synced to disk,
/// renamed onto `path`, and the directory synced so that the rename itself survives a crash. Readers
/// see either the old file or the complete new one, never a partial file.
///
/// The temporary file's name is unique to this call and recognisable as a leftover (see the
/// module documentation). On any error (from `write`, the flush, the sync or the rename) the
/// temporary file is removed and the target is left untouched; only a process killed while writing
/// leaves it, for [`remove_temporaries`] to clear. If the target exists, the new file gets its
/// permissions; otherwise the usual ones for a new file (`0o666` less the umask on Unix, not the
/// `0o600` of a bare temporary file).
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
    let directory = directory_of(path);
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
    builder
        .prefix(&prefix)
        .suffix(SUFFIX)
        .rand_bytes(RANDOM_CHARS);
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
    sync_directory(directory)
}

/// The directory `path` is in: its parent, or the current directory for a bare file name.
fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Sync `directory`, so that a rename into it is on disk. Unix only: elsewhere a directory cannot be
/// opened as a file, and the rename is as durable as the system makes it.
fn sync_directory(directory: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    File::open(directory)?.sync_all()?;
    #[cfg(not(unix))]
    let _ = directory;
    Ok(())
}

/// The target file name of a temporary file [`write_atomically`] names `name`, or `None` if `name` is
/// not one: `.{target}.{six letters or digits}.tmp` with a non-empty target.
fn temporary_target(name: &OsStr) -> Option<&str> {
    let rest = name.to_str()?.strip_prefix('.')?.strip_suffix(SUFFIX)?;
    let (target, random) = rest.split_at_checked(rest.len().checked_sub(RANDOM_CHARS + 1)?)?;
    let random = random.strip_prefix('.')?;
    (!target.is_empty() && random.bytes().all(|b| b.is_ascii_alphanumeric())).then_some(target)
}

/// Whether `name` is the name of a temporary file of [`write_atomically`]: one that a process killed
/// while writing may have left.
///
/// ```
/// use std::ffi::OsStr;
/// use hooke_mesh::io::is_temporary;
/// assert!(is_temporary(OsStr::new(".frame_0004.obj.KuyPid.tmp")));
/// assert!(!is_temporary(OsStr::new("frame_0004.obj")));
/// ```
pub fn is_temporary(name: &OsStr) -> bool {
    temporary_target(name).is_some()
}

/// Remove every temporary file of [`write_atomically`] in `dir` (not in its subdirectories): the
/// leftovers of a killed writer. A command that writes into a directory of its own calls this when it
/// starts, so that the directory then holds only complete files. A missing `dir` has none.
///
/// Another process writing into `dir` at the same time would lose its temporary file (and fail with
/// an error): call it only on a directory the caller owns.
///
/// # Errors
/// [`MeshError::Io`] naming the directory or the file that could not be listed or removed.
///
/// Returns how many files were removed.
pub fn remove_temporaries(dir: &Path) -> Result<usize, MeshError> {
    remove_matching(dir, |_| true)
}

/// Remove the temporary files of [`write_atomically`] for `path` alone (`.{name}.??????.tmp` beside
/// it): the leftovers of a killed writer of that one file, for a command that writes a few named
/// files into a directory that is not its own.
///
/// # Errors
/// As [`remove_temporaries`].
///
/// Returns how many files were removed.
pub fn remove_temporaries_of(path: &Path) -> Result<usize, MeshError> {
    let Some(name) = path.file_name().and_then(OsStr::to_str) else {
        return Ok(0);
    };
    remove_matching(directory_of(path), |target| target == name)
}

fn remove_matching(dir: &Path, keep_target: impl Fn(&str) -> bool) -> Result<usize, MeshError> {
    let io = |path: &Path, source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    };
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io(dir, e)),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry.map_err(|e| io(dir, e))?;
        let name = entry.file_name();
        if !temporary_target(&name).is_some_and(&keep_target) {
            continue;
        }
        // Only files: a directory of that name is not ours.
        if !entry.file_type().is_ok_and(|t| t.is_file()) {
            continue;
        }
        let path = entry.path();
        match std::fs::remove_file(&path) {
            Ok(()) => removed += 1,
            // Gone already (its writer finished or failed meanwhile).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&path, e)),
        }
    }
    Ok(removed)
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

    #[test]
    fn each_writer_has_its_own_recognisable_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame_0004.obj");
        let mut seen = Vec::new();
        // A second writer of the same target while the first is still writing.
        write_atomically(&path, |out| {
            write_atomically(&path, |inner| {
                seen = entries(dir.path());
                inner.write_all(b"inner")
            })
            .map_err(std::io::Error::other)?;
            out.write_all(b"outer")
        })
        .unwrap();
        assert_eq!(seen.len(), 2, "{seen:?}");
        assert_ne!(seen[0], seen[1]);
        for name in &seen {
            assert_eq!(temporary_target(OsStr::new(name)), Some("frame_0004.obj"));
        }
        assert_eq!(std::fs::read(&path).unwrap(), b"outer");
        assert_eq!(entries(dir.path()), vec!["frame_0004.obj"]);
    }

    #[test]
    fn temporary_names_are_recognised_exactly() {
        for name in [
            ".a.KuyPid.tmp",
            ".frame_0004.obj.KuyPid.tmp",
            "..x.000000.tmp",
        ] {
            assert!(is_temporary(OsStr::new(name)), "{name}");
        }
        for name in [
            "a.KuyPid.tmp",    // not hidden
            "..KuyPid.tmp",    // no target
            ".a.Kuy-id.tmp",   // not tempfile's alphabet
            ".a.KuyPi.tmp",    // five random characters
            ".a.KuyPidd.tmp",  // seven, the dot in the wrong place
            ".a.KuyPid.tmp.x", // another suffix
            ".a.tmp",          // a fixed temporary name: not ours
            "frame_0004.obj",
        ] {
            assert!(!is_temporary(OsStr::new(name)), "{name}");
        }
    }

    #[test]
    fn leftovers_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "a.txt",
            ".a.txt.KuyPid.tmp",
            ".b.txt.AbC123.tmp",
            "notes.tmp",
            ".hidden",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        std::fs::create_dir(dir.path().join(".c.txt.Dir000.tmp")).unwrap();
        assert_eq!(remove_temporaries_of(&dir.path().join("a.txt")).unwrap(), 1);
        assert_eq!(
            entries(dir.path()),
            vec![
                ".b.txt.AbC123.tmp",
                ".c.txt.Dir000.tmp",
                ".hidden",
                "a.txt",
                "notes.tmp"
            ]
        );
        assert_eq!(remove_temporaries(dir.path()).unwrap(), 1);
        assert_eq!(
            entries(dir.path()),
            vec![".c.txt.Dir000.tmp", ".hidden", "a.txt", "notes.tmp"]
        );
        assert_eq!(remove_temporaries(&dir.path().join("missing")).unwrap(), 0);
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

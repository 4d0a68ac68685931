//! Atomic file output: write to a temporary name, rename into place when complete.
//!
//! A crash, a full disk or an encoder error part-way through never leaves a truncated file
//! under the final name: readers see either the old file (or none) or the complete new one.
//!
//! Temporary files are named `.<name>.<pid>-<n>.tmp` beside the target and recorded while
//! they exist, so that an interrupted program can remove them ([`remove_temporaries`], which
//! the command line calls on SIGINT and SIGTERM): an interrupted write leaves nothing behind.
//! Error messages never mention the temporary name.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Temporary files that exist now, to be removed if the program is interrupted.
static IN_FLIGHT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Makes temporary names unique within the process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary file recorded in [`IN_FLIGHT`]; dropping it removes the file (if it is still
/// there, i.e. was not renamed into place) and the record.
struct Temporary {
    path: PathBuf,
}

impl Temporary {
    /// Creates `.<name>.<pid>-<n>.tmp` in `dir`, recorded before it is created so that an
    /// interruption in between still finds it.
    fn create(dir: &Path, name: &std::ffi::OsStr) -> io::Result<(Self, File)> {
        let mut file_name = std::ffi::OsString::from(".");
        file_name.push(name);
        file_name.push(format!(
            ".{}-{}.tmp",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let path = dir.join(file_name);
        if let Ok(mut list) = IN_FLIGHT.lock() {
            list.push(path.clone());
        }
        let temporary = Self { path };
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        // The output gets the permissions `File::create` would give it (0o666 less the
        // umask), which `create_new` also uses.
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            options.mode(0o666);
        }
        let file = options.open(&temporary.path)?;
        Ok((temporary, file))
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        if let Ok(mut list) = IN_FLIGHT.lock() {
            list.retain(|p| p != &self.path);
        }
    }
}

/// The temporary files of the writes in progress now.
pub fn temporaries() -> Vec<PathBuf> {
    IN_FLIGHT
        .lock()
        .map(|list| list.clone())
        .unwrap_or_default()
}

/// Removes every temporary file that a write in progress has created. For signal handlers:
/// call it, then exit.
pub fn remove_temporaries() {
    if let Ok(list) = IN_FLIGHT.lock() {
        for path in list.iter() {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The directory a file path lives in (`.` for a bare name).
fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Writes a file atomically: `write` fills a temporary file in the same directory as `path`,
/// which is flushed, synced and renamed over `path` only when `write` returns `Ok`.
///
/// On any error (from `write`, from the file system, or a `path` without a file name) the
/// temporary file is removed and `path` is left as it was. The new file gets the usual
/// permissions of a newly created file (0o666 less the umask on Unix). The temporary file
/// lives beside the target because a rename is only atomic within one file system.
///
/// See also `std::fs::write` (not atomic).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    let Some(file_name) = path.file_name() else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} does not name a file", path.display()),
        ));
    };
    let (temporary, file) = Temporary::create(directory_of(path), file_name)?;
    let mut out = BufWriter::new(file);
    write(&mut out)?;
    let file = out.into_inner().map_err(io::IntoInnerError::into_error)?;
    file.sync_all()?;
    drop(file);
    std::fs::rename(&temporary.path, path)?;
    drop(temporary);
    Ok(())
}

/// Checks, before any long work, that [`write_atomically`] could write `path`: it names a
/// file (not a directory) in an existing directory where a file can be created. Nothing is
/// left behind.
pub fn check_writable(path: &Path) -> io::Result<()> {
    let Some(file_name) = path.file_name() else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "does not name a file",
        ));
    };
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is a directory, not a file",
        ));
    }
    let dir = directory_of(path);
    if !dir.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("directory {} does not exist", dir.display()),
        ));
    }
    let (probe, _file) = Temporary::create(dir, file_name)?;
    drop(probe);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_complete_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write_atomically(&path, |w| w.write_all(b"hello")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"hello");
        assert_eq!(entries(dir.path()), vec!["out.txt"]);
    }

    #[test]
    fn replaces_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        std::fs::write(&path, b"old").unwrap();
        write_atomically(&path, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
    }

    #[test]
    fn failing_writer_keeps_old_file_and_removes_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        std::fs::write(&path, b"old").unwrap();
        let err = write_atomically(&path, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("encoder failed"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "encoder failed");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["out.txt"]);
    }

    #[test]
    fn missing_directory_is_an_error_and_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no_such_dir").join("out.txt");
        assert!(write_atomically(&path, |w| w.write_all(b"x")).is_err());
        assert!(!path.exists());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn interrupted_writes_can_be_cleaned_up() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        let err = write_atomically(&path, |w| {
            w.write_all(b"partial")?;
            w.flush()?;
            // What a signal handler sees in the middle of a write (other tests may be
            // writing elsewhere at the same time, so only this directory's are removed).
            let ours: Vec<PathBuf> = temporaries()
                .into_iter()
                .filter(|p| p.parent() == Some(dir.path()))
                .collect();
            assert_eq!(ours.len(), 1);
            assert_eq!(entries(dir.path()).len(), 1);
            for p in ours {
                std::fs::remove_file(p).unwrap();
            }
            assert!(entries(dir.path()).is_empty());
            Err(io::Error::other("interrupted"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "interrupted");
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn path_without_file_name_is_an_error() {
        let err = write_atomically(Path::new("/"), |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[cfg(unix)]
    #[test]
    fn new_file_gets_the_permissions_of_file_create() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write_atomically(&path, |w| w.write_all(b"x")).unwrap();
        let plain = dir.path().join("plain.txt");
        std::fs::File::create(&plain).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&path), mode(&plain));
    }
}

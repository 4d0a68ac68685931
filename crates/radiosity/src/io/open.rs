//! The one way input files are opened: checked to be regular files before they are opened,
//! and read up to a size cap.
//!
//! Without these checks a named pipe (FIFO) given as a scene, an `mtllib` or an `include`
//! blocks forever in `open()`, and `/dev/zero` or `/dev/urandom` is read until memory runs
//! out. Every reader goes through [`read_to_string_checked`] (or [`open_checked`] for a
//! reader that streams), with the cap for its kind of file from [`Kind`], so a new format
//! (glTF, MGF, IES, …) gets the same policy with one call.
//!
//! The checks, in order:
//! 1. `metadata` (which follows symbolic links and never blocks) must say *regular file*:
//!    a directory, FIFO, socket or device is refused without opening it;
//! 2. its length must be at most the cap;
//! 3. the opened file is checked again (it may have been swapped between the two calls),
//!    and at most cap + 1 bytes are read, so a file that grows while it is read (or a
//!    special file that reports length 0, as `/proc` files do) still stops at the cap.
//!
//! Errors are [`std::io::Error`]s whose message says what is wrong without the path; callers
//! put the path in their own error (the scene errors name the file once).

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// One mebibyte, for caps.
pub const MIB: u64 = 1 << 20;

/// The kinds of input file and their size caps.
///
/// The caps are far above any real input of the kind (the 101k-polygon office scene is
/// a few MB of OBJ) and far below what would exhaust memory once parsed (a parsed OBJ
/// takes a few times its text).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Geometry: OBJ, glTF/GLB, MGF, a scene file with inline surfaces. 512 MiB.
    Geometry,
    /// A material library (MTL) or another small side file. 64 MiB.
    Materials,
    /// A photometric file (IES LM-63, EULUMDAT). 16 MiB.
    Photometry,
    /// A saved solution (JSON, every element). 2 GiB.
    Solution,
    /// A small problem or settings file (a form-factor problem). 64 MiB.
    Small,
}

impl Kind {
    /// The largest file of this kind that is read, bytes.
    pub const fn cap(self) -> u64 {
        match self {
            Kind::Geometry => 512 * MIB,
            Kind::Materials => 64 * MIB,
            Kind::Photometry => 16 * MIB,
            Kind::Solution => 2048 * MIB,
            Kind::Small => 64 * MIB,
        }
    }

    /// What the kind is called in messages.
    pub const fn noun(self) -> &'static str {
        match self {
            Kind::Geometry => "scene file",
            Kind::Materials => "material library",
            Kind::Photometry => "photometric file",
            Kind::Solution => "solution file",
            Kind::Small => "input file",
        }
    }
}

/// What a path is, when it is not a regular file.
fn file_type_problem(meta: &std::fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("is a directory, not a file");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("is a named pipe (FIFO), not a regular file");
        }
        if t.is_socket() {
            return Some("is a socket, not a regular file");
        }
        if t.is_char_device() || t.is_block_device() {
            return Some("is a device, not a regular file");
        }
    }
    Some("is not a regular file")
}

fn too_large(len: u64, kind: Kind) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "is {}, larger than the {} MiB accepted for a {}",
            human_size(len),
            kind.cap() / MIB,
            kind.noun()
        ),
    )
}

/// `n` bytes in a unit a person reads at a glance.
fn human_size(n: u64) -> String {
    if n >= 10 * MIB {
        format!("{} MiB", n / MIB)
    } else if n >= 10 * 1024 {
        format!("{} KiB", n / 1024)
    } else {
        format!("{n} bytes")
    }
}

/// Opens `path` for reading after checking that it is a regular file of at most
/// `kind.cap()` bytes (see the module documentation). The returned reader stops after
/// cap + 1 bytes; [`read_to_string_checked`] turns reaching that into an error.
pub fn open_checked(path: &Path, kind: Kind) -> io::Result<io::Take<File>> {
    let meta = std::fs::metadata(path)?;
    if let Some(problem) = file_type_problem(&meta) {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, problem));
    }
    if meta.len() > kind.cap() {
        return Err(too_large(meta.len(), kind));
    }
    let file = File::open(path)?;
    // Checked again on the open file: the path may have changed since `metadata`.
    let meta = file.metadata()?;
    if let Some(problem) = file_type_problem(&meta) {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, problem));
    }
    Ok(file.take(kind.cap() + 1))
}

/// Reads a whole file as bytes through [`open_checked`]: a regular file of at most
/// `kind.cap()` bytes.
pub fn read_checked(path: &Path, kind: Kind) -> io::Result<Vec<u8>> {
    let mut reader = open_checked(path, kind)?;
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes)?;
    if bytes.len() as u64 > kind.cap() {
        return Err(too_large(bytes.len() as u64, kind));
    }
    Ok(bytes)
}

/// Reads a whole file as UTF-8 text through [`open_checked`]: a regular file of at most
/// `kind.cap()` bytes. A leading byte-order mark is kept (parsers strip it).
pub fn read_to_string_checked(path: &Path, kind: Kind) -> io::Result<String> {
    let bytes = read_checked(path, kind)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("is not UTF-8 text (invalid byte at line {line}, byte offset {at})"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_regular_files_and_refuses_directories() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, "v 0 0 0\n").unwrap();
        assert_eq!(
            read_to_string_checked(&path, Kind::Geometry).unwrap(),
            "v 0 0 0\n"
        );
        let err = read_to_string_checked(dir.path(), Kind::Geometry).unwrap_err();
        assert!(err.to_string().contains("directory"), "{err}");
        let missing = read_to_string_checked(&dir.path().join("no.obj"), Kind::Geometry);
        assert_eq!(missing.unwrap_err().kind(), io::ErrorKind::NotFound);
    }

    #[test]
    fn invalid_utf8_names_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.mtl");
        std::fs::write(&path, b"newmtl a\nKd \xff 0 0\n").unwrap();
        let err = read_to_string_checked(&path, Kind::Materials).unwrap_err();
        assert!(err.to_string().contains("line 2"), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_refused_without_reading() {
        // /dev/zero would otherwise be read until memory runs out.
        let err = read_to_string_checked(Path::new("/dev/zero"), Kind::Materials).unwrap_err();
        assert!(err.to_string().contains("device"), "{err}");
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("zero.mtl");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let err = read_to_string_checked(&link, Kind::Materials).unwrap_err();
        assert!(err.to_string().contains("device"), "{err}");
    }

    #[test]
    fn sizes_read_at_a_glance() {
        assert_eq!(human_size(512), "512 bytes");
        assert_eq!(human_size(20 * 1024), "20 KiB");
        assert_eq!(human_size(3 << 30), "3072 MiB");
    }
}

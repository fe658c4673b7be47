//! Atomic file writes: every brainshift output (meshes, images, fields, pictures, reports)
//! is written to a temporary sibling in the same directory and renamed into place only after
//! the whole file was written and flushed to disk. A reader never sees a partial file, a
//! failed or interrupted write leaves any previous file untouched, and the temporary file
//! is removed on failure.
//!
//! * [`write_atomic`]: bytes through a buffered writer;
//! * [`write_via`]: a writer that wants a path of its own (an image library choosing
//!   compression by the name, a plotting backend), given a temporary path that keeps the
//!   final name's suffix;
//! * [`temporary_sibling`]: that path.
//!
//! Files: `lib.rs` only (the three functions and their tests).
//!
//! Architecture invariant: the standard library only; no brainshift crate below it, and no
//! file format.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The temporary sibling a write of `path` goes through: in `path`'s directory, hidden
/// (a leading dot), unique per process and call, ending in `keep_suffix` (e.g. `".nii.gz"`,
/// for writers that choose their format by the name; `""` for none).
pub fn temporary_sibling(path: &Path, keep_suffix: &str) -> PathBuf {
    static CALLS: AtomicUsize = AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, Ordering::Relaxed);
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // No dot inside the stem: a writer that reads the suffix from the last dots finds
    // `keep_suffix` only.
    let stem: String = name.strip_suffix(keep_suffix).unwrap_or(&name).replace('.', "_");
    dir.join(format!(".{stem}-{}-{call}-partial{keep_suffix}", std::process::id()))
}

/// Writes `path` by `write(temporary)` and renames the temporary file into place once it
/// succeeded; on any error the temporary file is removed and `path` left as it was. `write`
/// must close (and should flush) the file it writes.
pub fn write_via(
    path: &Path,
    keep_suffix: &str,
    write: impl FnOnce(&Path) -> io::Result<()>,
) -> io::Result<()> {
    let tmp = temporary_sibling(path, keep_suffix);
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `path` through a buffered writer on a temporary sibling, flushed and synced to
/// disk, then renamed into place ([`write_via`]).
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    write_via(path, "", |tmp| {
        let mut buf = io::BufWriter::new(std::fs::File::create(tmp)?);
        write(&mut buf)?;
        buf.into_inner().map_err(|e| e.into_error())?.sync_all()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("bs-atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_write_appears_whole_and_leaves_nothing_beside_it() {
        let d = dir("whole");
        let path = d.join("out.csv");
        write_atomic(&path, |w| w.write_all(b"a,b\n1,2\n")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"a,b\n1,2\n");
        assert_eq!(entries(&d), ["out.csv"]);
    }

    #[test]
    fn a_failed_write_keeps_the_previous_file_and_removes_its_partial_one() {
        let d = dir("failed");
        let path = d.join("field.nii.gz");
        std::fs::write(&path, b"previous").unwrap();
        let e = write_atomic(&path, |w| {
            w.write_all(b"half of it")?;
            Err(io::Error::other("the disk is full"))
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "the disk is full");
        assert_eq!(std::fs::read(&path).unwrap(), b"previous");
        assert_eq!(entries(&d), ["field.nii.gz"]);
        // The same through a path-taking writer that wrote its file and then failed.
        let e = write_via(&path, ".nii.gz", |tmp| {
            std::fs::write(tmp, b"half")?;
            Err(io::Error::other("the encoder failed"))
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "the encoder failed");
        assert_eq!(entries(&d), ["field.nii.gz"]);
    }

    #[test]
    fn the_temporary_file_is_a_hidden_unique_sibling_keeping_the_suffix() {
        let a = temporary_sibling(Path::new("out/warped.t1.nii.gz"), ".nii.gz");
        let b = temporary_sibling(Path::new("out/warped.t1.nii.gz"), ".nii.gz");
        assert_ne!(a, b);
        assert_eq!(a.parent(), Some(Path::new("out")));
        let name = a.file_name().unwrap().to_str().unwrap();
        assert!(name.starts_with(".warped_t1-") && name.ends_with("-partial.nii.gz"), "{name}");
        // The only dots: the leading one and the suffix's.
        assert_eq!(name.matches(".").count(), 3, "{name}");
        let bare = temporary_sibling(Path::new("report.json"), "");
        assert_eq!(bare.parent(), Some(Path::new(".")));
    }
}

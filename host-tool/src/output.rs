//! Writing results atomically: a file is either complete or absent.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::HostError;

/// Writes `bytes` to `path` through a temporary file in the same directory and
/// a rename, so a failure never leaves a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), HostError> {
    write_all_atomic(&[(path, bytes)])
}

/// Writes every file or none: each goes first to a temporary file beside its
/// target, and only once all of them are complete on disk are they renamed
/// into place. A failure before that removes the temporary files and leaves
/// the targets as they were. (A rename that fails after others succeeded,
/// which a rename within one directory does only on a failing disk, still
/// leaves the earlier ones in place.)
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> Result<(), HostError> {
    let mut staged = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        match stage(path, bytes) {
            Ok(tmp) => staged.push((tmp, path)),
            Err(e) => {
                staged.iter().for_each(|(tmp, _)| drop(std::fs::remove_file(tmp)));
                return Err(e);
            }
        }
    }
    let mut renamed = staged.into_iter().map(|(tmp, path)| {
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            cannot_write(path, e)
        })
    });
    renamed.try_for_each(|r| r)
}

/// Checks, before a long run, that each of `paths` can be written: its
/// directory exists and takes a new file, and the path is not a directory.
pub fn check_writable(paths: &[&Path]) -> Result<(), HostError> {
    for (i, &path) in paths.iter().enumerate() {
        if paths.iter().skip(i + 1).any(|&other| other == path) {
            return Err(HostError::Input(format!("two outputs would both be written to {}", path.display())));
        }
        if path.is_dir() {
            return Err(HostError::Io(format!("cannot write {}: it is a directory", path.display())));
        }
        let tmp = stage(path, &[])?;
        let _ = std::fs::remove_file(tmp);
    }
    Ok(())
}

/// Writes `bytes` to a new temporary file beside `path`; returns its path.
fn stage(path: &Path, bytes: &[u8]) -> Result<PathBuf, HostError> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name =
        path.file_name().ok_or_else(|| HostError::Io(format!("{} is not a file path", path.display())))?;
    let tmp = dir.join(format!(".{}.tmp-{}", name.to_string_lossy(), std::process::id()));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    match written {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(cannot_write(path, e))
        }
    }
}

fn cannot_write(path: &Path, e: std::io::Error) -> HostError {
    HostError::Io(format!("cannot write {}: {e}", path.display()))
}

/// Encodes an 8-bit RGB image as PNG.
pub fn png(width: u16, height: u16, rgb: &[u8]) -> Result<Vec<u8>, HostError> {
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    image::ImageEncoder::write_image(
        encoder,
        rgb,
        u32::from(width),
        u32::from(height),
        image::ExtendedColorType::Rgb8,
    )
    .map_err(|e| HostError::Io(format!("cannot encode PNG: {e}")))?;
    Ok(out)
}

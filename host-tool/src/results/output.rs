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
///
/// A target that exists and is no regular file (`/dev/null`, a FIFO) is
/// written in place, once the others are staged: renaming over it would
/// replace the device with a file. A symbolic link is followed, so the
/// link stays and its target is replaced.
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> Result<(), HostError> {
    let mut staging = Staging::default();
    for &(path, bytes) in files {
        staging.add(path, bytes)?;
    }
    staging.commit()
}

/// Files written in full beside their targets, renamed into place together
/// by [`Staging::commit`]; dropped uncommitted, it removes what it staged and
/// the targets stay as they were (see [`write_all_atomic`]).
#[derive(Debug, Default)]
pub struct Staging {
    /// (temporary file, target) of each regular file.
    staged: Vec<(PathBuf, PathBuf)>,
    /// Devices and FIFOs, written in place once the rest is staged.
    in_place: Vec<(PathBuf, Vec<u8>)>,
}

impl Staging {
    /// Stages `bytes` for `path`.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), HostError> {
        let target = resolve(path);
        if is_special(&target) {
            self.in_place.push((target, bytes.to_vec()));
        } else {
            let tmp = stage(&target, bytes)?;
            self.staged.push((tmp, target));
        }
        Ok(())
    }

    /// Stages an empty file for `path` that the caller fills as it goes (a
    /// file too large to hold in memory); it must be complete and closed
    /// before [`Staging::commit`].
    pub fn open(&mut self, path: &Path) -> Result<std::fs::File, HostError> {
        let target = resolve(path);
        let tmp = temporary(&target)?;
        let file = std::fs::File::create(&tmp).map_err(|e| cannot_write(path, e))?;
        self.staged.push((tmp, target));
        Ok(file)
    }

    /// Renames every staged file into place, then writes the devices.
    pub fn commit(mut self) -> Result<(), HostError> {
        for (tmp, target) in std::mem::take(&mut self.staged) {
            std::fs::rename(&tmp, &target).map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                cannot_write(&target, e)
            })?;
        }
        for (target, bytes) in std::mem::take(&mut self.in_place) {
            std::fs::write(&target, bytes).map_err(|e| cannot_write(&target, e))?;
        }
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Checks, before a long run, that each of `paths` can be written: its
/// directory exists and takes a new file, and the path is not a directory.
/// A device or FIFO is left alone: opening one to try it would already hand
/// its reader an empty stream.
pub fn check_writable(paths: &[&Path]) -> Result<(), HostError> {
    for (i, &path) in paths.iter().enumerate() {
        if paths.iter().skip(i + 1).any(|&other| other == path) {
            return Err(HostError::Input(format!("two outputs would both be written to {}", path.display())));
        }
        let target = resolve(path);
        if target.is_dir() {
            return Err(HostError::Io(format!("cannot write {}: it is a directory", path.display())));
        }
        if is_special(&target) {
            continue;
        }
        let tmp = stage(&target, &[])?;
        let _ = std::fs::remove_file(tmp);
    }
    Ok(())
}

/// The file `path` names: an existing symbolic link's target, else `path`.
fn resolve(path: &Path) -> PathBuf {
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    if is_link {
        std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
    } else {
        path.to_path_buf()
    }
}

/// Whether `path` exists and is neither a regular file nor a directory.
fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Writes `bytes` to a new temporary file beside `path`; returns its path.
fn stage(path: &Path, bytes: &[u8]) -> Result<PathBuf, HostError> {
    let tmp = temporary(path)?;
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

/// The temporary file's name beside `path`.
fn temporary(path: &Path) -> Result<PathBuf, HostError> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name =
        path.file_name().ok_or_else(|| HostError::Io(format!("{} is not a file path", path.display())))?;
    Ok(dir.join(format!(".{}.tmp-{}", name.to_string_lossy(), std::process::id())))
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

/// Refuses to replace a file an earlier run left at any of `paths` (devices
/// such as /dev/null excepted), naming the first and the options that help.
pub fn refuse_overwrite(paths: &[&Path]) -> Result<(), HostError> {
    match paths.iter().find(|p| std::fs::metadata(p).is_ok_and(|m| m.is_file())) {
        Some(p) => Err(HostError::Input(format!(
            "{} exists, from an earlier run; add --overwrite to replace it, or write elsewhere with --out-dir DIR",
            p.display()
        ))),
        None => Ok(()),
    }
}

/// Refuses an image name whose extension is not `.png`, the one format the
/// host writes (PNG bytes under another name would mislead every viewer).
pub fn check_png_name(path: &Path) -> Result<(), HostError> {
    let png = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png || is_special(&resolve(path)) {
        Ok(())
    } else {
        Err(HostError::Input(format!("{}: images are written as PNG; name the file .png", path.display())))
    }
}

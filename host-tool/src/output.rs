//! Writing results atomically: a file is either complete or absent.

use std::io::Write;
use std::path::Path;

use crate::error::HostError;

/// Writes `bytes` to `path` through a temporary file in the same directory and
/// a rename, so a failure never leaves a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), HostError> {
    let io = |e: std::io::Error| HostError::Io(format!("cannot write {}: {e}", path.display()));
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name =
        path.file_name().ok_or_else(|| HostError::Io(format!("{} is not a file path", path.display())))?;
    let tmp = dir.join(format!(".{}.tmp-{}", name.to_string_lossy(), std::process::id()));
    let result = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    if let Err(e) = result.and_then(|()| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    Ok(())
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

//! The image from what the nodes traced. With supersampling the nodes trace
//! an image `side` times larger along each axis, so every pixel holds a
//! regular `side` x `side` grid of samples; a pixel is the mean of its block.
//! The block sums stay integers, so the image is as bit-identical across
//! arrays as the samples are.

use glam::DVec3;

use crate::error::{HostError, input};
use crate::session::frame::check_size;

/// The most samples per pixel: an 8 x 8 grid.
pub const MAX_SAMPLES: u16 = 64;

/// Samples per pixel along each image axis for `samples` per pixel, which
/// must be a square from 1 to [`MAX_SAMPLES`].
pub fn sample_side(samples: u16) -> Result<u16, HostError> {
    (1..=8u16).find(|k| k * k == samples).ok_or_else(|| {
        input(format!(
            "--samples must be a square from 1 to {MAX_SAMPLES} (1, 4, 9, 16, 25, 36, 49, 64), got {samples}"
        ))
    })
}

/// The samples traced along each axis for a `size` image at `samples` a
/// pixel, both sizes checked ([`check_size`]).
pub fn traced(size: [u16; 2], samples: u16) -> Result<[u16; 2], HostError> {
    let [w, h] = size;
    check_size(w, h)?;
    let side = sample_side(samples)?;
    let (Some(tw), Some(th)) = (w.checked_mul(side), h.checked_mul(side)) else {
        return Err(HostError::ImageSize(format!(
            "image size {w}x{h} at {samples} samples a pixel traces over 65535 samples along an axis: \
             lower --size or --samples"
        )));
    };
    check_size(tw, th).map_err(|e| match samples {
        1 => e,
        _ => e.context(&format!("at --samples {samples} the nodes trace {tw}x{th} samples")),
    })?;
    Ok([tw, th])
}

/// Sums each `side` x `side` block of a `width` x `height` buffer (row
/// major) into one pixel of the `width / side` x `height / side` image.
pub fn block_sums(sums: &[[u64; 3]], width: u16, height: u16, side: u16) -> Vec<[u64; 3]> {
    block(sums, width, height, side, [0; 3], |acc, s| {
        for (a, v) in acc.iter_mut().zip(s) {
            *a += v;
        }
    })
}

/// The mean of each `side` x `side` block of a `width` x `height` buffer of
/// linear colours.
pub fn block_means(colors: &[DVec3], width: u16, height: u16, side: u16) -> Vec<DVec3> {
    let n = f64::from(side) * f64::from(side);
    block(colors, width, height, side, DVec3::ZERO, |acc, c| *acc += *c).into_iter().map(|c| c / n).collect()
}

fn block<T: Copy, A: Copy>(
    buf: &[T],
    width: u16,
    height: u16,
    side: u16,
    zero: A,
    add: impl Fn(&mut A, &T),
) -> Vec<A> {
    let side = usize::from(side.max(1));
    let (w, h) = (usize::from(width), usize::from(height));
    let (pw, ph) = (w / side, h / side);
    let mut out = vec![zero; pw * ph];
    for y in 0..ph * side {
        for x in 0..pw * side {
            if let (Some(acc), Some(v)) = (out.get_mut(y / side * pw + x / side), buf.get(y * w + x)) {
                add(acc, v);
            }
        }
    }
    out
}

/// The mean of `samples` linear Q1.15 contributions summed in `sum`, as an
/// 8-bit sRGB value (same integers in, same byte out).
pub fn to_srgb8_mean(sum: u64, samples: u64) -> u8 {
    let linear = (sum as f64 / (32768.0 * samples.max(1) as f64)).clamp(0.0, 1.0);
    let s = if linear <= 0.003_130_8 { 12.92 * linear } else { 1.055 * linear.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

/// A linear Q1.15 sum of one sample as an 8-bit sRGB value.
pub fn to_srgb8(sum: u64) -> u8 {
    to_srgb8_mean(sum, 1)
}

/// The 8-bit sRGB image of a `width` x `height` buffer of sample sums with
/// `side` x `side` samples per pixel.
pub fn srgb8(sums: &[[u64; 3]], width: u16, height: u16, side: u16) -> Vec<u8> {
    let n = u64::from(side) * u64::from(side);
    block_sums(sums, width, height, side).iter().flat_map(|px| px.map(|s| to_srgb8_mean(s, n))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_is_the_mean_of_its_block_of_samples() {
        // 4 x 2 samples, two per axis: two pixels.
        let sums: Vec<[u64; 3]> = (0..8u64).map(|i| [i, 10 * i, 0]).collect();
        // Pixel 0 holds samples 0, 1, 4, 5; pixel 1 holds 2, 3, 6, 7.
        assert_eq!(block_sums(&sums, 4, 2, 2), vec![[10, 100, 0], [18, 180, 0]]);
        let colors: Vec<DVec3> = (0..8).map(|i| DVec3::splat(f64::from(i))).collect();
        assert_eq!(block_means(&colors, 4, 2, 2), vec![DVec3::splat(2.5), DVec3::splat(4.5)]);
        assert_eq!(block_sums(&sums, 4, 2, 1), sums);
    }

    #[test]
    fn one_sample_maps_as_before_and_a_mean_as_its_value() {
        // 32768 is 1.0 linear: white. Half of it, twice, is white as a mean of two.
        assert_eq!(to_srgb8(32768), 255);
        assert_eq!(to_srgb8_mean(32768, 2), to_srgb8(16384));
        assert_eq!(to_srgb8_mean(4 * 1000, 4), to_srgb8(1000));
    }

    #[test]
    fn samples_must_be_a_square_up_to_64() {
        assert_eq!(sample_side(1).unwrap(), 1);
        assert_eq!(sample_side(16).unwrap(), 4);
        assert_eq!(sample_side(64).unwrap(), 8);
        for bad in [0, 2, 8, 81] {
            assert_eq!(sample_side(bad).unwrap_err().exit_code(), 17);
        }
    }
}

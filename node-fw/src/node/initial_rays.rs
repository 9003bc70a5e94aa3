//! Initial rays: this node's tile of pixels, created in a scattered order
//! and started where they enter the grid.

use link_proto::ErrorCode;

use crate::camera::{primary_line, primary_ray};
use crate::digital_line::DigitalLine;
use crate::pool::Stage;

use super::{Node, Phase, Work, retire_to_background};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// Whether initial rays of this node's tile remain to be created.
    pub(super) fn creation_left(&self) -> bool {
        self.phase == Phase::Rendering && self.render.is_some_and(|r| self.cursor < tile_pixels(&r.tile))
    }

    /// Creates the next initial ray of the tile and starts it at its entry cube
    /// (or retires it to the background if it misses the grid).
    pub(super) fn create_initial(&mut self, work: &mut Work) {
        let Some(r) = self.render else { return };
        let [x0, y0, x1, _] = r.tile.map(u32::from);
        let width = x1.saturating_sub(x0).max(1);
        let pixels = u64::from(tile_pixels(&r.tile).max(1));
        // The cursor-th pixel of a scattered order (stride coprime to the
        // pixel count, so every pixel comes once); below u32 as `% pixels`.
        let k = u32::try_from(u64::from(self.cursor) * u64::from(self.stride) % pixels).unwrap_or(0);
        let (x, y) = (x0 + k % width, y0 + k / width);
        self.cursor += 1;
        work.created += 1;
        let Ok(line) = primary_line(&r.camera, x as u16, y as u16) else {
            return self.fail(ErrorCode::OutOfRange, crate::error::Field::Direction as u32, 0);
        };
        let mut ray = primary_ray(&line, y * u32::from(r.size[0]) + x, r.credit);
        let stage = match DigitalLine::enter(&line, &self.grid) {
            Some(walk) => {
                ray.cell = walk.cell().map(|c| c as u16);
                Stage::Trace
            }
            None => Stage::Retire(retire_to_background(&self.scene(), &ray)),
        };
        if self.pool.admit(ray, stage).is_err() {
            // can_admit(0) was checked: unreachable, but never lose the ray.
            self.cursor -= 1;
        }
    }
}

/// A stride through `n` pixels near `n / phi`, coprime to `n`: creating
/// initial rays in the order `k * stride mod n` spreads each stretch of time's
/// rays over the whole tile, so the work's distribution over the scene stays
/// the same all frame (scanline order sweeps it across the scene, and sliding
/// boundaries would chase it).
pub fn scatter_stride(n: u32) -> u32 {
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let n64 = u64::from(n.max(1));
    // 0.6180339887 in Q16 is 40503.
    let mut s = ((n64 * 40503) >> 16).max(1);
    while gcd(s, n64) != 1 {
        s += 1;
    }
    // s < n unless n = 1, where any stride gives pixel 0.
    u32::try_from(s % n64).unwrap_or(1)
}

/// Pixels of a tile `[x0, y0, x1, y1]`.
pub(super) fn tile_pixels(tile: &[u16; 4]) -> u32 {
    let [x0, y0, x1, y1] = tile.map(u32::from);
    x1.saturating_sub(x0) * y1.saturating_sub(y0)
}

#[cfg(test)]
mod tests {
    use super::scatter_stride;

    #[test]
    fn the_scattered_order_visits_every_pixel_once() {
        for n in 1..=3000u32 {
            let s = u64::from(scatter_stride(n));
            let mut seen = [false; 3000];
            for k in 0..u64::from(n) {
                let p = (k * s % u64::from(n)) as usize;
                assert!(!seen[p], "n = {n}: pixel {p} twice");
                seen[p] = true;
            }
            if n >= 100 {
                // Near n / phi: consecutive rays land far apart.
                assert!((0.6..0.65).contains(&(s as f64 / f64::from(n))), "n = {n}: stride {s}");
            }
        }
    }
}

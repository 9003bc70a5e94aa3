//! Initial rays from the eye through pixels, in integer arithmetic.

use link_proto::{CameraMsg, RayKind, RayMsg};

use crate::error::Error;
use crate::geometry::{Direction, Line, Point};
use crate::shading::Q15_ONE;

/// The quantised line from the eye through the centre of pixel `(x, y)`.
///
/// Direction `corner + x du + y dv` is summed exactly in i64 and normalised by
/// [`Direction::normalize`], so every node creates the same bits for a pixel.
pub fn primary_line(camera: &CameraMsg, x: u16, y: u16) -> Result<Line, Error> {
    let eye = Point::from_bits(camera.eye)?;
    let mut v = [0i64; 3];
    for (axis, out) in v.iter_mut().enumerate() {
        let c = |a: &[i32; 3]| i64::from(a.get(axis).copied().unwrap_or(0));
        *out = c(&camera.corner) + i64::from(x) * c(&camera.du) + i64::from(y) * c(&camera.dv);
    }
    Ok(Line::new(eye, Direction::normalize(v)?))
}

/// The initial ray along `line` for `pixel`, full weight, not yet placed in a cube.
pub fn primary_ray(line: &Line, pixel: u32, credit: u64) -> RayMsg {
    RayMsg {
        origin: line.origin(),
        dir: line.dir(),
        cell: [0; 3],
        pixel,
        weight: [Q15_ONE; 3],
        credit,
        kind: RayKind::Primary,
        depth: 0,
        ignore: None,
        best: None,
        t_max: None,
        class: 0,
        tag: 0,
    }
}

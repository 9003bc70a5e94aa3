//! Conversions from f64 test geometry to the firmware's raw formats.

use node_fw::{Direction, Line, Point};

/// Rounds cubes to raw Q16.16.
pub fn pos(x: f64) -> i32 {
    (x * 65536.0).round() as i32
}

/// Raw Q16.16 of a point.
pub fn point_raw(p: [f64; 3]) -> [i32; 3] {
    p.map(pos)
}

/// The firmware's line through `o` along `d` (any length, nonzero).
pub fn line(o: [f64; 3], d: [f64; 3]) -> Line {
    Line::new(Point::from_bits(point_raw(o)).expect("origin in range"), direction(d))
}

/// Rounds a direction of any length to a unit Q2.30 direction.
pub fn direction(d: [f64; 3]) -> Direction {
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let raw = d.map(|c| (c / len * (1u64 << 30) as f64).round() as i32);
    Direction::from_bits(raw).expect("unit direction")
}

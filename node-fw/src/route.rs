//! Where a ray goes when its cube is not in this node's subregion.
//!
//! Dimension-order routing with the driving axis last: boundaries across the
//! non-driving axes are whole planes shared by every node, so a ray first moves
//! to the row of nodes that holds its cube; along the driving axis each row has
//! its own boundaries (they slide), and the ray then walks the row to the owner.
//! This is the paper's forwarding rule for boundary discrepancy (Fig. 6), and it
//! needs nothing but the node's own box.

use crate::cube_box::CubeBox;
use crate::link::Port;

/// The port toward `cell`, or `None` if `cell` lies in `bounds`.
pub fn toward(bounds: &CubeBox, cell: [i32; 3], driving_axis: usize) -> Option<Port> {
    let order = [(driving_axis + 1) % 3, (driving_axis + 2) % 3, driving_axis];
    for axis in order {
        let c = cell.get(axis).copied().unwrap_or(0);
        let lo = i32::from(bounds.lo.get(axis).copied().unwrap_or(0));
        let hi = i32::from(bounds.hi.get(axis).copied().unwrap_or(0));
        if c < lo {
            return Some(Port::toward(axis, false));
        }
        if c >= hi {
            return Some(Port::toward(axis, true));
        }
    }
    None
}

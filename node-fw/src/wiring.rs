//! Which neighbour ports a node uses, and how a board with few UARTs maps them.
//!
//! A node at `coord` of an `array` has a neighbour on a port when the next
//! node along that axis exists. Boards with fewer than six neighbour UARTs
//! (the emulated mps2-an385 has four besides the host's) give their UARTs to
//! the ports that exist, in [`Port::NEIGHBOURS`] order: UART 1 to the first,
//! UART 2 to the second, and so on. The host wires emulated boards by the same
//! rule, so both ends agree without configuration.

use heapless::Vec;

use crate::link::Port;

/// The node index of `coord` in `array` (x fastest, then y, then z), or
/// `None` when `coord` lies outside the array.
pub fn index_of(coord: [u16; 3], array: [u16; 3]) -> Option<u16> {
    if coord.iter().zip(array).any(|(&c, n)| c >= n) {
        return None;
    }
    let [x, y, z] = coord.map(u32::from);
    let [nx, ny, _] = array.map(u32::from);
    u16::try_from(x + nx * (y + ny * z)).ok()
}

/// The index of the node on `port` of node `index`, if the array has one there.
pub fn neighbour_of(index: usize, port: Port, array: [u16; 3]) -> Option<u16> {
    let axis = port.axis()?;
    let mut coord = coord_of(index, array);
    let c = coord.get_mut(axis)?;
    *c = if port.index().is_multiple_of(2) { c.checked_add(1)? } else { c.checked_sub(1)? };
    index_of(coord, array)
}

/// The coordinate of node `index` in `array` (the inverse of [`index_of`]).
pub fn coord_of(index: usize, array: [u16; 3]) -> [u16; 3] {
    let [nx, ny, _] = array.map(|n| usize::from(n.max(1)));
    [(index % nx) as u16, ((index / nx) % ny) as u16, (index / (nx * ny)) as u16]
}

/// The neighbour ports that exist for `coord` in `array`, in port order.
pub fn neighbour_ports(coord: [u16; 3], array: [u16; 3]) -> Vec<Port, 6> {
    let mut ports = Vec::new();
    for port in Port::NEIGHBOURS {
        let Some(axis) = port.axis() else { continue };
        let (c, n) = (coord.get(axis).copied().unwrap_or(0), array.get(axis).copied().unwrap_or(1));
        let exists = if port.index().is_multiple_of(2) { c + 1 < n } else { c > 0 };
        if exists {
            // At most six neighbour ports exist, so this never overflows.
            let _ = ports.push(port);
        }
    }
    ports
}

/// The port served by each neighbour UART of a board with `U` of them (`None`
/// for an unused UART), or the first port left without a UART.
///
/// With six or more UARTs the map is fixed, UART `i` serving
/// `Port::NEIGHBOURS[i]`, so a physical array is cabled the same way at every
/// node. With fewer, the UARTs go to the ports that exist, in port order.
pub fn uart_ports<const U: usize>(coord: [u16; 3], array: [u16; 3]) -> Result<[Option<Port>; U], Port> {
    let ports = neighbour_ports(coord, array);
    let mut map = [None; U];
    if U >= Port::NEIGHBOURS.len() {
        for (slot, port) in map.iter_mut().zip(Port::NEIGHBOURS) {
            *slot = ports.contains(&port).then_some(port);
        }
        return Ok(map);
    }
    if let Some(&missing) = ports.get(U) {
        return Err(missing);
    }
    for (slot, &port) in map.iter_mut().zip(ports.iter()) {
        *slot = Some(port);
    }
    Ok(map)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_of_2x2x2_has_three_neighbours() {
        let ports = neighbour_ports([0, 1, 0], [2, 2, 2]);
        assert_eq!(ports.as_slice(), &[Port::PosX, Port::NegY, Port::PosZ]);
    }

    #[test]
    fn interior_needs_six_and_four_uarts_do_not_do() {
        assert_eq!(neighbour_ports([1, 1, 1], [3, 3, 3]).len(), 6);
        assert_eq!(uart_ports::<4>([1, 1, 1], [3, 3, 3]), Err(Port::PosZ));
        let map = uart_ports::<4>([1, 0, 0], [3, 2, 1]);
        assert_eq!(map, Ok([Some(Port::PosX), Some(Port::NegX), Some(Port::PosY), None]));
    }

    #[test]
    fn six_uarts_are_cabled_the_same_everywhere() {
        let map = uart_ports::<6>([0, 1, 0], [2, 2, 1]);
        assert_eq!(map, Ok([Some(Port::PosX), None, None, Some(Port::NegY), None, None]));
    }

    #[test]
    fn neighbours_by_port_stay_inside_the_array() {
        // Node 5 of 2x2x2 sits at (1,0,1).
        assert_eq!(neighbour_of(5, Port::NegX, [2, 2, 2]), Some(4));
        assert_eq!(neighbour_of(5, Port::PosY, [2, 2, 2]), Some(7));
        assert_eq!(neighbour_of(5, Port::NegZ, [2, 2, 2]), Some(1));
        assert_eq!(neighbour_of(5, Port::PosX, [2, 2, 2]), None);
        assert_eq!(neighbour_of(0, Port::NegY, [2, 2, 2]), None);
        assert_eq!(neighbour_of(0, Port::Host, [2, 2, 2]), None);
    }

    #[test]
    fn index_is_row_major_and_checked() {
        assert_eq!(index_of([1, 0, 0], [2, 2, 2]), Some(1));
        assert_eq!(index_of([1, 1, 1], [2, 2, 2]), Some(7));
        assert_eq!(index_of([0, 0, 3], [4, 4, 3]), None);
        assert_eq!(coord_of(7, [2, 2, 2]), [1, 1, 1]);
        assert_eq!(coord_of(5, [3, 2, 1]), [2, 1, 0]);
    }
}

//! The cabling check: are the boards behind the serial devices cabled as the
//! array needs, and if not, which cable is wrong?
//!
//! Every board says hello on each neighbour link with its unique id, and tells
//! the host which id it found at each port ([`link_proto::PeerNote`]). Node
//! `i` of the array is the board on device `i`; its `+X` port must reach the
//! board of its `+X` neighbour, and so on. From the same reports the devices
//! can also be put in array order ([`order`]): the one corner with no `-X`,
//! `-Y` or `-Z` neighbour is the origin, and the cables say where every other
//! board sits.

use std::collections::HashMap;

use link_proto::{BoardId, BoardInfo};
use node_fw::Port;
use node_fw::wiring::{coord_of, index_of, neighbour_of};

/// What one device's board told the host.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reported {
    /// The serial device.
    pub device: String,
    /// The board, from its hello.
    pub board: BoardInfo,
    /// The board found at each neighbour port (port order), from its notes.
    pub peers: [Option<BoardId>; 6],
}

/// What a port reaches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reaches {
    /// The board of this node.
    Node(usize),
    /// A board that is on none of the devices.
    Unlisted(BoardId),
    /// Nothing has said hello there.
    Nothing,
}

/// One thing wrong with the cabling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// A board cannot tell itself apart (no id, or one another board has too).
    Unidentified {
        /// The node.
        node: usize,
    },
    /// `port` of `node` reaches another board than its neighbour's, or none.
    Wrong {
        /// The node.
        node: usize,
        /// Its port.
        port: Port,
        /// What the port reaches.
        found: Reaches,
        /// The node it should reach.
        expected: usize,
    },
    /// Two cables of one node are plugged into each other's sockets.
    Swapped {
        /// The node.
        node: usize,
        /// The two ports.
        ports: (Port, Port),
    },
}

/// Whether every port the array needs has reported a board (there is
/// nothing more to wait for).
pub fn complete(reported: &[Reported], array: [u16; 3]) -> bool {
    reported.iter().enumerate().all(|(node, r)| {
        Port::NEIGHBOURS
            .iter()
            .all(|&p| neighbour_of(node, p, array).is_none() || r.peers[p.index()].is_some())
    })
}

/// Everything wrong with the cabling of `array` with node `i` on device `i`
/// (nothing when it is right).
pub fn check(reported: &[Reported], array: [u16; 3]) -> Vec<Fault> {
    let index = match board_index(reported) {
        Ok(index) => index,
        Err(node) => return vec![Fault::Unidentified { node }],
    };
    let mut wrong = Vec::new();
    for (node, r) in reported.iter().enumerate() {
        for port in Port::NEIGHBOURS {
            let Some(expected) = neighbour_of(node, port, array).map(usize::from) else { continue };
            let found = match r.peers[port.index()] {
                None => Reaches::Nothing,
                Some(id) => index.get(&id).map_or(Reaches::Unlisted(id), |&n| Reaches::Node(n)),
            };
            if found != Reaches::Node(expected) {
                wrong.push(Fault::Wrong { node, port, found, expected });
            }
        }
    }
    pair_swaps(wrong)
}

/// Device index of each board id; the error is a node whose board has no id,
/// or the same id as an earlier one.
fn board_index(reported: &[Reported]) -> Result<HashMap<BoardId, usize>, usize> {
    let mut index = HashMap::new();
    for (node, r) in reported.iter().enumerate() {
        if !r.board.id.is_known() || index.insert(r.board.id, node).is_some() {
            return Err(node);
        }
    }
    Ok(index)
}

/// Replaces two wrong ports of one node that each reach the other's
/// neighbour by one swap.
fn pair_swaps(wrong: Vec<Fault>) -> Vec<Fault> {
    let reaches = |f: &Fault| match *f {
        Fault::Wrong { node, port, found: Reaches::Node(found), expected } => {
            Some((node, port, found, expected))
        }
        _ => None,
    };
    let mut used = vec![false; wrong.len()];
    let mut faults = Vec::new();
    for i in 0..wrong.len() {
        if used[i] {
            continue;
        }
        let partner = reaches(&wrong[i]).and_then(|(node, _, found, expected)| {
            (i + 1..wrong.len()).find(|&j| {
                !used[j]
                    && reaches(&wrong[j]).is_some_and(|(n, _, f, e)| n == node && f == expected && e == found)
            })
        });
        match (partner, reaches(&wrong[i])) {
            (Some(j), Some((node, port, _, _))) => {
                let other = reaches(&wrong[j]).map_or(port, |(_, p, _, _)| p);
                used[j] = true;
                faults.push(Fault::Swapped { node, ports: (port, other) });
            }
            _ => faults.push(wrong[i]),
        }
    }
    faults
}

/// The port's name as the docs write it.
pub fn port_name(port: Port) -> &'static str {
    match port {
        Port::PosX => "+X",
        Port::NegX => "-X",
        Port::PosY => "+Y",
        Port::NegY => "-Y",
        Port::PosZ => "+Z",
        Port::NegZ => "-Z",
        Port::Host => "host",
    }
}

/// "node 1 (1,0,0) on DEVICE".
fn node_name(node: usize, reported: &[Reported], array: [u16; 3]) -> String {
    let [x, y, z] = coord_of(node, array);
    let device = reported.get(node).map_or("?", |r| r.device.as_str());
    format!("node {node} ({x},{y},{z}) on {device}")
}

/// "the board on DEVICE (node 1 (1,0,0))".
fn board_name(node: usize, reported: &[Reported], array: [u16; 3]) -> String {
    let [x, y, z] = coord_of(node, array);
    let device = reported.get(node).map_or("?", |r| r.device.as_str());
    format!("the board on {device} (node {node} ({x},{y},{z}))")
}

/// One sentence naming the fault and the cables involved.
pub fn describe(fault: &Fault, reported: &[Reported], array: [u16; 3]) -> String {
    match *fault {
        Fault::Unidentified { node } => format!(
            "{}: its board has no unique id, or the same as another's ({}); its firmware cannot be checked",
            node_name(node, reported, array),
            reported.get(node).map_or(BoardId::NONE, |r| r.board.id)
        ),
        Fault::Wrong { node, port, found, expected } => {
            let reaches = match found {
                Reaches::Node(n) => board_name(n, reported, array),
                Reaches::Unlisted(id) => format!("board {id}, which is on none of the given devices"),
                Reaches::Nothing => "no board".to_string(),
            };
            format!(
                "{}: its {} link reaches {reaches}, expected {}",
                node_name(node, reported, array),
                port_name(port),
                board_name(expected, reported, array)
            )
        }
        Fault::Swapped { node, ports: (a, b) } => format!(
            "{}: its {} and {} cables are swapped",
            node_name(node, reported, array),
            port_name(a),
            port_name(b)
        ),
    }
}

/// The device of each node of `array` (node order), read from the cabling;
/// the error says why no order fits.
pub fn order(reported: &[Reported], array: [u16; 3]) -> Result<Vec<usize>, String> {
    let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
    if reported.len() != nodes {
        return Err(format!("{} devices for the {} nodes of the array", reported.len(), nodes));
    }
    let index =
        board_index(reported).map_err(|d| format!("the board on {} has no unique id", reported[d].device))?;
    let reach = |d: usize, p: Port| reported[d].peers[p.index()].and_then(|id| index.get(&id).copied());
    let corners: Vec<usize> = (0..nodes)
        .filter(|&d| [Port::NegX, Port::NegY, Port::NegZ].iter().all(|&p| reach(d, p).is_none()))
        .collect();
    let [origin] = corners[..] else {
        return Err(format!(
            "{} boards have no -X, -Y and -Z neighbour; the array's origin corner must be the only one",
            corners.len()
        ));
    };
    let mut coords: Vec<Option<[u16; 3]>> = vec![None; nodes];
    coords[origin] = Some([0; 3]);
    let mut queue = vec![origin];
    while let Some(d) = queue.pop() {
        let c = coords[d].unwrap_or_default();
        for port in Port::NEIGHBOURS {
            let Some(e) = reach(d, port) else { continue };
            let axis = port.axis().unwrap_or(0);
            let mut next = c;
            let step =
                if port.index() % 2 == 0 { next[axis].checked_add(1) } else { next[axis].checked_sub(1) };
            match step.filter(|&v| v < array[axis]) {
                Some(v) => next[axis] = v,
                None => {
                    return Err(format!(
                        "the board on {} is cabled beyond the {}x{}x{} array",
                        reported[e].device, array[0], array[1], array[2]
                    ));
                }
            }
            match coords[e] {
                Some(seen) if seen != next => {
                    return Err(format!(
                        "the board on {} is cabled both at ({},{},{}) and ({},{},{})",
                        reported[e].device, seen[0], seen[1], seen[2], next[0], next[1], next[2]
                    ));
                }
                Some(_) => {}
                None => {
                    coords[e] = Some(next);
                    queue.push(e);
                }
            }
        }
    }
    let mut device_of = vec![usize::MAX; nodes];
    for (d, c) in coords.iter().enumerate() {
        let Some(c) = c else {
            return Err(format!("the board on {} is cabled to none of the others", reported[d].device));
        };
        let node = index_of(*c, array).map_or(0, usize::from);
        if device_of[node] != usize::MAX {
            return Err(format!(
                "the boards on {} and {} are both cabled at ({},{},{})",
                reported[device_of[node]].device, reported[d].device, c[0], c[1], c[2]
            ));
        }
        device_of[node] = d;
    }
    let ordered: Vec<Reported> = device_of.iter().map(|&d| reported[d].clone()).collect();
    match check(&ordered, array).first() {
        Some(fault) => Err(describe(fault, &ordered, array)),
        None => Ok(device_of),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use link_proto::BoardKind;

    /// Boards cabled as `array` needs, node `i` with id `100 + i` on device `di`.
    fn cabled(array: [u16; 3]) -> Vec<Reported> {
        let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
        (0..nodes)
            .map(|node| Reported {
                device: format!("d{node}"),
                board: BoardInfo {
                    id: BoardId([100 + node as u32, 0, 0]),
                    kind: BoardKind::Simulated,
                    ..BoardInfo::HOST
                },
                peers: Port::NEIGHBOURS
                    .map(|p| neighbour_of(node, p, array).map(|n| BoardId([100 + u32::from(n), 0, 0]))),
            })
            .collect()
    }

    #[test]
    fn a_correct_array_passes() {
        for array in [[1, 1, 1], [2, 1, 1], [2, 2, 2], [3, 3, 3], [4, 2, 1]] {
            let r = cabled(array);
            assert!(complete(&r, array));
            assert_eq!(check(&r, array), vec![]);
        }
    }

    #[test]
    fn devices_listed_out_of_order_are_named_and_put_back() {
        let array = [2, 2, 2];
        let mut r = cabled(array);
        r.swap(1, 2);
        // From node 0 the two boards look like crossed cables.
        let faults = check(&r, array);
        assert_eq!(describe(&faults[0], &r, array), "node 0 (0,0,0) on d0: its +X and +Y cables are swapped");
        assert_eq!(order(&r, array).expect("an order fits"), [0, 2, 1, 3, 4, 5, 6, 7]);
        // A rotation of every device: the order is read back from the cables.
        let mut shuffled = cabled(array);
        shuffled.rotate_left(3);
        let order = order(&shuffled, array).expect("an order fits");
        let names: Vec<&str> = order.iter().map(|&d| shuffled[d].device.as_str()).collect();
        assert_eq!(names, ["d0", "d1", "d2", "d3", "d4", "d5", "d6", "d7"]);
    }

    #[test]
    fn two_cables_of_one_node_plugged_into_each_others_sockets_are_a_swap() {
        let array = [2, 2, 1];
        let mut r = cabled(array);
        // Node 0's +X cable goes to node 2, its +Y cable to node 1; at the far
        // ends the two cables land in -Y of node 2 and -X of node 1.
        r[0].peers.swap(Port::PosX.index(), Port::PosY.index());
        let (n1, n2) = (Port::NegX.index(), Port::NegY.index());
        r[1].peers[n1] = None;
        r[1].peers[Port::NegY.index()] = Some(BoardId([100, 0, 0]));
        r[2].peers[n2] = None;
        r[2].peers[Port::NegX.index()] = Some(BoardId([100, 0, 0]));
        let faults = check(&r, array);
        assert_eq!(faults[0], Fault::Swapped { node: 0, ports: (Port::PosX, Port::PosY) });
        assert_eq!(describe(&faults[0], &r, array), "node 0 (0,0,0) on d0: its +X and +Y cables are swapped");
        assert!(faults[1..].iter().all(|f| matches!(f, Fault::Wrong { found: Reaches::Nothing, .. })));
    }

    #[test]
    fn a_missing_cable_and_a_stranger_are_named() {
        let array = [2, 1, 1];
        let mut r = cabled(array);
        r[0].peers[Port::PosX.index()] = None;
        r[1].peers[Port::NegX.index()] = Some(BoardId([7, 0, 0]));
        assert!(!complete(&r, array));
        let text: Vec<String> = check(&r, array).iter().map(|f| describe(f, &r, array)).collect();
        assert_eq!(
            text,
            [
                "node 0 (0,0,0) on d0: its +X link reaches no board, expected the board on d1 (node 1 (1,0,0))",
                "node 1 (1,0,0) on d1: its -X link reaches board 00000007, which is on none of the given devices, \
                 expected the board on d0 (node 0 (0,0,0))",
            ]
        );
    }

    #[test]
    fn boards_without_ids_or_with_one_id_cannot_be_checked_or_ordered() {
        let array = [2, 1, 1];
        let mut r = cabled(array);
        r[1].board.id = r[0].board.id;
        assert_eq!(check(&r, array), vec![Fault::Unidentified { node: 1 }]);
        assert!(order(&r, array).is_err());
        r[1].board.id = BoardId::NONE;
        assert_eq!(check(&r, array), vec![Fault::Unidentified { node: 1 }]);
    }

    #[test]
    fn an_array_cabled_larger_than_asked_for_has_no_order() {
        let r = cabled([4, 1, 1]);
        let err = order(&r, [2, 2, 1]).unwrap_err();
        assert!(err.contains("beyond the 2x2x1 array"), "{err}");
    }
}

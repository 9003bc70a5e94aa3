//! Nodes learn which board is at the end of each of their links and tell the
//! host, on clean and on lossy links: what the cabling check is built on.

use link_proto::{BoardId, Message};
use node_fw::Port;
use node_fw::wiring::neighbour_of;
use sim_board::board::board_id;
use sim_board::{Board, Faults, HostEndpoint, SimConfig};

/// Collects the peer notes of `nodes` nodes; finished once `want` holds.
struct Notes {
    peers: Vec<[Option<BoardId>; 6]>,
    hellos: usize,
    want: Vec<[Option<BoardId>; 6]>,
}

impl HostEndpoint for Notes {
    fn receive(&mut self, node: u16, _at: u64, msg: Message) {
        match msg {
            Message::Peer(note) => self.peers[usize::from(node)][usize::from(note.port)] = Some(note.board),
            Message::Hello(_) => self.hellos += 1,
            _ => {}
        }
    }

    fn finished(&self) -> bool {
        self.peers == self.want
    }
}

/// The id of the board at each port of each node, from the array's geometry.
fn expected(array: [u16; 3]) -> Vec<[Option<BoardId>; 6]> {
    let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
    (0..nodes)
        .map(|i| Port::NEIGHBOURS.map(|p| neighbour_of(i, p, array).map(|n| board_id(usize::from(n)))))
        .collect()
}

fn learn(config: SimConfig) {
    let array = config.array;
    let want = expected(array);
    let mut board = Board::new(config);
    let mut host = Notes { peers: vec![[None; 6]; want.len()], hellos: 0, want: want.clone() };
    board.run(&mut host).unwrap_or_else(|e| panic!("{array:?}: {e}"));
    assert_eq!(host.peers, want, "{array:?}: what the host was told");
    assert_eq!(host.hellos, want.len(), "{array:?}: one hello per node to the host");
    for (i, w) in want.iter().enumerate() {
        assert_eq!(&board.node(i).peers(), w, "{array:?}: node {i}'s own view");
    }
}

#[test]
fn every_node_learns_the_board_at_each_cable_and_tells_the_host() {
    for array in [[2, 1, 1], [2, 2, 2], [3, 3, 3], [4, 2, 1]] {
        learn(SimConfig::new(array));
    }
}

#[test]
fn the_neighbour_hellos_survive_lossy_links() {
    let faults = Faults { corrupt: 0.2, drop: 0.2, dup: 0.1, delay: 0.1, seed: 7 };
    for array in [[2, 2, 2], [3, 3, 1]] {
        learn(SimConfig { faults: Some(faults), ..SimConfig::new(array) });
    }
}

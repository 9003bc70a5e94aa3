//! The node firmware: one node of the array, driven by the host over UART 0.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use node_board::board::active as board;
use node_board::board::boot_count;
use node_board::run::{Idle, resend_after, run};
use node_board::wires::Wires;
use node_board::{BoardLinks, BoardNode};
use static_cell::ConstStaticCell;

// Static storage: the node and its channels are most of the RAM, known at link time.
// The node starts as zero bytes, made a new node at boot (`Node::renew`), so
// that the linker places it in zero-filled RAM (`.bss`): `BoardNode::new`'s
// value has non-zero bytes, and the whole of it (35 KiB on the mps2-an385)
// would be copied from flash. `scripts/firmware.sh` checks that it stays there.
// SAFETY: `mem::zeroed` in a static's initialiser is evaluated by the
// compiler, which refuses to build (E0080) unless all-zero bytes are a valid
// `BoardNode`; `node-fw/tests/renew.rs` holds `renew` to `new`.
#[allow(unsafe_code)]
static NODE: ConstStaticCell<BoardNode> = ConstStaticCell::new(unsafe { core::mem::zeroed() });
// All zero bytes (its time-out is set at boot), so the linker places it in
// zero-filled RAM (`.bss`) rather than copying initial values from flash;
// `scripts/firmware.sh` checks that it stays there.
static LINKS: ConstStaticCell<BoardLinks> = ConstStaticCell::new(BoardLinks::new(0));

#[entry]
fn main() -> ! {
    let board::Parts { host, neighbours, mut clock, info, mut lights } = board::init();
    node_board::log::booted(&info);
    let mut wires = Wires::new(host, neighbours);
    board::arm_wakeups();
    let idle = Idle { clear: board::clear_wakeups, sleep: board::sleep };
    let node = NODE.take();
    node.renew(0);
    node.set_board(info);
    let links = LINKS.take();
    links.set_timeout(resend_after(&clock));
    links.set_incarnation(boot_count::next_incarnation());
    run(node, links, &mut wires, &mut clock, &mut lights, idle)
}

//! The node firmware: one node of the array, driven by the host over UART 0.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use node_board::board::active as board;
use node_board::board::{boot_count, wake};
use node_board::run::{Idle, RESEND_AFTER, run};
use node_board::wires::Wires;
use node_board::{BoardLinks, BoardNode};
use static_cell::ConstStaticCell;

// Static storage: the node and its channels are most of the RAM, known at link time.
static NODE: ConstStaticCell<BoardNode> = ConstStaticCell::new(BoardNode::new(0));
static LINKS: ConstStaticCell<BoardLinks> = ConstStaticCell::new(BoardLinks::new(RESEND_AFTER));

#[entry]
fn main() -> ! {
    let (host, neighbours, mut clock) = board::init();
    let mut wires = Wires::new(host, neighbours);
    wake::arm(board::WAKE_PERIOD);
    let idle = Idle { clear: board::clear_wakeups, sleep: wake::sleep };
    let links = LINKS.take();
    links.set_incarnation(boot_count::next_incarnation());
    run(NODE.take(), links, &mut wires, &mut clock, idle)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // node-fw reports bad input as error messages; a panic is a bug. Stop, so
    // the host's time-out names this node.
    board::exit(false)
}

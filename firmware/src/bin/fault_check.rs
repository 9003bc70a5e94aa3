//! A firmware that fails on purpose, for the test that a board's last words
//! reach the host: it comes up as the node firmware does, lights its working
//! light, and panics.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use node_board::board::active as board;
use node_board::lights::Activity;

#[entry]
fn main() -> ! {
    let mut parts = board::init();
    parts.lights.show(Activity::Running);
    panic!("fault_check fails on purpose")
}

//! The bring-up log: defmt over RTT on a real board (probe-rs prints it),
//! nothing on the emulated boards, whose host link and QEMU say it all.
//!
//! What a person bringing up a physical array wants to see on each board:
//! who it is and how fast it runs, which board each cable reaches, and
//! whether the node failed.

use link_proto::{BoardId, BoardInfo};

#[cfg(feature = "stm32f413")]
use defmt_rtt as _;

/// The board came up.
pub fn booted(info: &BoardInfo) {
    #[cfg(feature = "stm32f413")]
    {
        let [lo, mid, hi] = info.id.0;
        defmt::info!(
            "board {=u32:08x}{=u32:08x}{=u32:08x}: core {=u32} Hz, links {=u32} baud, host {=u32} baud",
            hi,
            mid,
            lo,
            info.clock_hz,
            info.link_baud,
            info.host_baud
        );
    }
    let _ = info;
}

/// The board at the end of neighbour port `port` said hello.
pub fn peer(port: usize, id: BoardId) {
    #[cfg(feature = "stm32f413")]
    {
        let [lo, mid, hi] = id.0;
        defmt::info!("port {=usize} reaches board {=u32:08x}{=u32:08x}{=u32:08x}", port, hi, mid, lo);
    }
    let _ = (port, id);
}

/// The node stopped after reporting an error to the host.
pub fn failed() {
    #[cfg(feature = "stm32f413")]
    defmt::error!("the node failed; its error went to the host");
}

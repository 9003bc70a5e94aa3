//! Who is at the end of a link: the board a node runs on, as its hello names
//! it to the host and to its neighbours.
//!
//! A physical array is cabled by hand. Each board says hello on every
//! neighbour link with its [`BoardId`], and tells the host which board it
//! found on each of its ports ([`PeerNote`]), so the host can check the
//! cabling against the array it was asked for, and put the serial devices in
//! array order by itself.

use core::fmt;

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// A board's unique id: the chip's 96-bit unique device id on an STM32 (RM0430
/// §31.2, least significant word first), or one the host gave an emulated
/// board. All zero when the board has none.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default, Serialize, Deserialize, MaxSize,
)]
pub struct BoardId(pub [u32; 3]);

impl BoardId {
    /// No id: the board cannot tell itself apart.
    pub const NONE: BoardId = BoardId([0; 3]);

    /// Whether the board has an id.
    pub fn is_known(self) -> bool {
        self != Self::NONE
    }
}

/// Most significant word first, as ST's tools print the unique id; an id
/// that fits 32 bits (an emulated board's) prints as 8 digits.
impl fmt::Display for BoardId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [lo, mid, hi] = self.0;
        if hi == 0 && mid == 0 { write!(f, "{lo:08x}") } else { write!(f, "{hi:08x}{mid:08x}{lo:08x}") }
    }
}

/// What a node runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum BoardKind {
    /// The host itself (in the host's own hello).
    Host,
    /// A node of the in-memory board.
    Simulated,
    /// QEMU's mps2-an385 (Cortex-M3): the small-MCU image.
    Mps2An385,
    /// QEMU's netduinoplus2: the STM32 image with the emulated SoC's RAM.
    Netduinoplus2,
    /// A NUCLEO-F413ZH.
    NucleoF413zh,
}

impl BoardKind {
    /// The name the command line and the docs use.
    pub const fn name(self) -> &'static str {
        match self {
            BoardKind::Host => "host",
            BoardKind::Simulated => "in-memory",
            BoardKind::Mps2An385 => "mps2-an385",
            BoardKind::Netduinoplus2 => "netduinoplus2",
            BoardKind::NucleoF413zh => "nucleo-f413zh",
        }
    }

    /// Whether the board's UARTs serve fixed ports, so that it knows which
    /// board is at each port before it knows its place in the array. Boards
    /// with fewer than six neighbour UARTs hand them to the ports their place
    /// needs, so their cabling follows from the assignment.
    pub const fn fixed_ports(self) -> bool {
        !matches!(self, BoardKind::Mps2An385 | BoardKind::Host)
    }
}

/// Where a board's core clock comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum ClockSource {
    /// The PLL from an external clock (the ST-LINK's 8 MHz on a NUCLEO).
    PllFromExternal,
    /// The PLL from the internal oscillator.
    PllFromInternal,
    /// The reset clock: no PLL locked (an emulator's stub clock controller).
    Reset,
    /// An emulator counting instructions, or the in-memory board's virtual cycles.
    Virtual,
}

/// A firmware's version (the node firmware crate's semantic version).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct FirmwareVersion {
    /// Major.
    pub major: u8,
    /// Minor.
    pub minor: u8,
    /// Patch.
    pub patch: u8,
}

impl fmt::Display for FirmwareVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// What a board is and how it runs, as its hello tells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct BoardInfo {
    /// Unique id.
    pub id: BoardId,
    /// Kind of board.
    pub kind: BoardKind,
    /// The firmware's version.
    pub firmware: FirmwareVersion,
    /// Core clock in Hz, as the board set it up.
    pub clock_hz: u32,
    /// Where the core clock comes from.
    pub clock_source: ClockSource,
    /// Baud rate of the neighbour links (0 where links are not serial).
    pub link_baud: u32,
    /// Baud rate of the host link (0 where it is not serial).
    pub host_baud: u32,
}

impl BoardInfo {
    /// The host's own: no id, no clock, no links.
    pub const HOST: BoardInfo = BoardInfo {
        id: BoardId::NONE,
        kind: BoardKind::Host,
        firmware: FirmwareVersion { major: 0, minor: 0, patch: 0 },
        clock_hz: 0,
        clock_source: ClockSource::Virtual,
        link_baud: 0,
        host_baud: 0,
    };
}

/// Node to host: the board found at the end of one neighbour link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct PeerNote {
    /// The port, as node-fw numbers them: 0 +X, 1 -X, 2 +Y, 3 -Y, 4 +Z, 5 -Z.
    pub port: u8,
    /// The id the board there said hello with.
    pub board: BoardId,
}

/// Parses a decimal digit string at compile time (for `CARGO_PKG_VERSION_*`);
/// a value over 255 or a non-digit fails the build.
pub const fn version_part(s: &str) -> u8 {
    let mut rest = s.as_bytes();
    let mut value: u32 = 0;
    while let [d, tail @ ..] = rest {
        assert!(d.is_ascii_digit(), "version part is not a decimal number");
        value = value * 10 + (*d - b'0') as u32;
        assert!(value <= 255, "version part over 255");
        rest = tail;
    }
    value as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    extern crate std;
    use std::format;

    #[test]
    fn ids_print_as_st_tools_print_them() {
        let uid = BoardId([0x0047_0031, 0x3136_5111, 0x3332_3638]);
        assert_eq!(format!("{uid}"), "333236383136511100470031");
        assert_eq!(format!("{}", BoardId([0xbeef, 0, 0])), "0000beef");
    }

    #[test]
    fn version_parts_parse() {
        assert_eq!(version_part("0"), 0);
        assert_eq!(version_part("17"), 17);
        assert_eq!(version_part("255"), 255);
    }
}

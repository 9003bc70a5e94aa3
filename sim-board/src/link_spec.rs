//! Links of boards a user can build: a core clock, a line rate and a way of
//! moving bytes, turned into the cycles the in-memory board charges, with
//! named presets.
//!
//! A UART sends 10 bits per byte (start, eight data bits, stop), so a byte
//! occupies the wire for `clock * 10 / baud` cycles of the sending node. What
//! the node's CPU pays to move that byte between the UART and memory depends
//! on how the firmware does it ([`Transfer`]), and is charged to both ends as
//! messaging time. The message handling itself (framing, CRC, the reliable
//! channel) is the [`crate::CostModel`]'s, measured on the emulated Cortex-M3.

use clock_tree::nucleo_f413zh as nucleo;

use node_fw::reliable::WINDOW;

use crate::cost::LinkModel;

/// How a board moves a byte between a UART's data register and memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transfer {
    /// The main loop polls the status register and moves the byte.
    Polled,
    /// An interrupt per byte.
    Interrupt,
    /// A DMA stream moves the bytes; the CPU sets up whole transfers.
    Dma,
    /// Nothing: the ideal links, which cost the CPU no cycles at all.
    Free,
}

impl Transfer {
    /// CPU cycles per byte moved.
    ///
    /// - Interrupt: 12 cycles to enter and 10 to leave a handler (Cortex-M3
    ///   and M4 without floating-point context, ARM's TRMs), and the STM32
    ///   firmware's handler (the `interrupt-links` build's and the emulated
    ///   board's), counted instruction by instruction on its path in the
    ///   netduinoplus2 image's disassembly (`llvm-objdump -d` of
    ///   `target/firmware/node-netduinoplus2.elf` at `USART3`, which
    ///   `scripts/firmware.sh` builds, and whose size it holds): 32
    ///   instructions for a byte received (the handler's entry, the status
    ///   register read once, the data register, the byte into the ring, the
    ///   sending flag found clear; the two instructions an `it` skips
    ///   counted) and 25 for a byte sent (the status register, the flag, the
    ///   byte out of the ring and into the data register); 54 and 47 cycles
    ///   with the exception, 51 at each end. A lower bound: the peripheral
    ///   bus's wait states, a taken branch's refill, and the loop's moving of
    ///   each byte between ring and channel, are not counted.
    /// - Polled: the same register reads and ring update without the
    ///   exception: 16. (The loop must come round once per byte; a long walk
    ///   between passes delays bytes, which this model does not charge.)
    /// - DMA: none per byte ([`Transfer::cycles_per_frame`] charges its
    ///   transfers).
    ///
    /// These are estimates from the instruction sequences, not measurements:
    /// the emulated boards do not time their UARTs.
    pub const fn cycles_per_byte(self) -> u64 {
        match self {
            Transfer::Polled => 16,
            Transfer::Interrupt => 51,
            Transfer::Dma | Transfer::Free => 0,
        }
    }

    /// CPU cycles the sender pays a frame, beyond its bytes.
    ///
    /// - DMA: a frame goes as a transfer of the send stream (frames queued
    ///   together go as one, which this charges as one each: an upper
    ///   bound). Its completion interrupt hands the sent bytes back and
    ///   starts the next transfer: 43 to 48 instructions on that path in
    ///   the stm32f413 image (`llvm-objdump -d` at `DMA2_STREAM7`, the +X
    ///   link's send stream, and the other six; the `it`-skipped one
    ///   counted; the links whose rings lie 4 KiB or more into their array
    ///   build the address in five more), the longest 70 cycles with the
    ///   exception's 22. `scripts/firmware.sh` holds every handler's
    ///   size. The loop's start of an idle stream takes the same path
    ///   instead of the handler, and a receive stream's interrupt comes
    ///   once every 1 024 bytes (about 0.04 cycles a byte, not charged).
    /// - Polled and interrupt: none (their bytes are charged one by one);
    ///   free: none.
    pub const fn cycles_per_frame(self) -> u64 {
        match self {
            Transfer::Polled | Transfer::Interrupt | Transfer::Free => 0,
            Transfer::Dma => 70,
        }
    }

    /// The name on the command line and in summaries.
    pub const fn name(self) -> &'static str {
        match self {
            Transfer::Polled => "polled",
            Transfer::Interrupt => "interrupt",
            Transfer::Dma => "dma",
            Transfer::Free => "free",
        }
    }
}

/// One kind of link: clock, line rate, byte transfer, latency, buffering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkSpec {
    /// The node's core clock, Hz (virtual time counts its cycles).
    pub clock_hz: u64,
    /// Line rate, bits per second.
    pub baud: u64,
    /// How bytes reach memory.
    pub transfer: Transfer,
    /// Cycles from a message's last byte on the wire to its arrival.
    pub latency: u64,
    /// Messages the link holds before the sender sees it full.
    pub capacity: usize,
}

impl LinkSpec {
    /// Cycles one byte occupies the wire: 10 bits at `baud`, rounded up.
    pub fn byte_cycles(&self) -> u64 {
        (self.clock_hz * 10).div_ceil(self.baud.max(1)).max(1)
    }

    /// What the in-memory board charges for this link.
    pub fn model(&self) -> LinkModel {
        LinkModel {
            byte: self.byte_cycles(),
            byte_cpu: self.transfer.cycles_per_byte(),
            frame_cpu: self.transfer.cycles_per_frame(),
            latency: self.latency,
            capacity: self.capacity,
        }
    }
}

/// Named links: the neighbour links and the host link of a kind of board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinkPreset {
    /// NUCLEO-F413ZH boards as the firmware configures them
    /// ([`clock_tree::nucleo_f413zh`]): the core at its full 100 MHz from the
    /// PLL, neighbour USARTs at 3.125 Mbaud (the faster of the two rates
    /// near 3 Mbaud that both of its buses divide to exactly), and the host
    /// link through the ST-LINK's virtual COM port at 921 600 baud (a rate
    /// its bridge takes; set `--host-baud` to yours), every link's bytes
    /// moved by DMA.
    #[default]
    F413,
    /// The links the board charged before presets: 25 cycles a byte (40 Mbaud
    /// at 100 MHz) and no CPU per byte, on every link. Faster than any UART
    /// here; it shows what the nodes' own work allows.
    Ideal,
    /// The emulated boards (`render --backend qemu`: mps2-an385 under
    /// `-icount shift=0`): cycles are instructions, and every byte is moved
    /// through a polled UART register.
    Emulated,
}

impl LinkPreset {
    /// Every preset, for help texts and tests.
    pub const ALL: [LinkPreset; 3] = [LinkPreset::F413, LinkPreset::Ideal, LinkPreset::Emulated];

    /// The name on the command line and in summaries.
    pub const fn name(self) -> &'static str {
        match self {
            LinkPreset::F413 => "f413",
            LinkPreset::Ideal => "ideal",
            LinkPreset::Emulated => "emulated",
        }
    }

    /// Node-to-node links.
    pub const fn neighbour(self) -> LinkSpec {
        match self {
            LinkPreset::F413 => LinkSpec {
                clock_hz: nucleo::SYSCLK as u64,
                baud: nucleo::NEIGHBOUR_BAUD as u64,
                transfer: Transfer::Dma,
                latency: 2_000,
                capacity: WINDOW,
            },
            LinkPreset::Ideal => LinkSpec {
                clock_hz: 100_000_000,
                baud: 40_000_000,
                transfer: Transfer::Free,
                latency: 2_000,
                capacity: 8,
            },
            // QEMU's mps2-an385 under `-icount shift=0`: a cycle is an
            // instruction, and a UART's bytes cross a host socket far faster
            // than the CPU moves them, one register read or write each.
            LinkPreset::Emulated => LinkSpec {
                clock_hz: 1_000_000_000,
                baud: 1_000_000_000,
                transfer: Transfer::Polled,
                latency: 2_000,
                capacity: WINDOW,
            },
        }
    }

    /// Cycles a board spends in its loop's pass around each poll that did
    /// work, beyond what the cost model's kernels measure (see
    /// [`crate::CostModel::pass`]).
    ///
    /// The emulated boards' is fitted to their running times: the 2x2x2
    /// array rendering the quick start's frame (64x64, 60 spheres, seed 3,
    /// grid 16^3, static): the busiest node's emulated running time less
    /// what the in-memory board charges it, over its polls that did work,
    /// gives 35 600 instructions (three QEMU runs, median); the 24x24 frame
    /// of `tests/tests/emulated.rs` gives 18 300 (five runs). One figure fits
    /// both only so far: the preset takes 21 000, which charges the test
    /// frame's busiest node 7.6% too much and the quick start's 26.0% too
    /// little (docs/links.md; measured at commit cf232d9, frames masked). A poll's pass grew with the pieces of work a
    /// poll does ([`node_fw::node::PIECES_PER_POLL`]; one piece a poll fitted
    /// 9 390 and 6 195): the pass moves every byte those pieces send through a
    /// UART register, so it is more a cost a message than a cost a poll,
    /// which a figure a poll follows only roughly. The emulated nodes spent
    /// 30% less on the test frame with six pieces a poll than with one
    /// (2.44e6 instructions against 3.36e6-3.58e6). Tracing node 0 (QEMU
    /// `-singlestep -d exec`) finds its passes moving every byte through a
    /// UART register, and the frame decoder copying what arrived a few bytes
    /// at a time. The other presets stand for boards whose UARTs move bytes
    /// by interrupt or DMA, whose pass is not measured yet: none is charged.
    pub const fn loop_pass(self) -> u64 {
        match self {
            LinkPreset::Emulated => 21_000,
            LinkPreset::F413 | LinkPreset::Ideal => 0,
        }
    }

    /// Node-to-host links (the host reads many nodes and buffers more).
    pub const fn host(self) -> LinkSpec {
        let n = self.neighbour();
        match self {
            // A board's host channel holds its window.
            LinkPreset::F413 => LinkSpec { baud: nucleo::HOST_BAUD as u64, ..n },
            LinkPreset::Emulated => n,
            LinkPreset::Ideal => LinkSpec { capacity: 64, ..n },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_time_is_ten_bits_at_the_line_rate() {
        // Computed by hand: 100 MHz x 10 bits / 3.125 Mbaud = 320 cycles.
        let f413 = LinkPreset::F413.neighbour();
        assert_eq!(f413.byte_cycles(), 320);
        assert_eq!(LinkPreset::F413.host().byte_cycles(), 1_086);
        // The ideal preset is the board's former fixed link.
        let ideal = LinkPreset::Ideal.neighbour().model();
        assert_eq!((ideal.byte, ideal.byte_cpu, ideal.latency, ideal.capacity), (25, 0, 2_000, 8));
        assert_eq!(ideal.frame_cpu, 0);
        assert_eq!(LinkPreset::Ideal.host().model().capacity, 64);
    }

    #[test]
    fn the_boards_move_every_links_bytes_by_dma() {
        // As the stm32f413 image does (firmware/src/board/dma_link.rs).
        assert_eq!(LinkPreset::F413.neighbour().transfer, Transfer::Dma);
        assert_eq!(LinkPreset::F413.host().transfer, Transfer::Dma);
        let (n, h) = (LinkPreset::F413.neighbour().model(), LinkPreset::F413.host().model());
        assert_eq!((n.byte_cpu, n.frame_cpu), (0, 70));
        // An interrupt per run starts at its entry and exit: more than 22.
        assert!(n.frame_cpu > 22);
        assert_eq!((h.byte_cpu, h.frame_cpu), (0, 70));
        // Only the line rate tells the host link apart.
        assert_eq!(
            LinkSpec { baud: LinkPreset::F413.neighbour().baud, ..LinkPreset::F413.host() },
            LinkPreset::F413.neighbour()
        );
    }

    #[test]
    fn a_byte_costs_the_cpu_by_how_it_moves() {
        let spec = |transfer| LinkSpec { transfer, ..LinkPreset::F413.neighbour() }.model().byte_cpu;
        assert!(spec(Transfer::Free) == 0 && spec(Transfer::Dma) < spec(Transfer::Polled));
        assert!(spec(Transfer::Polled) < spec(Transfer::Interrupt));
        // An interrupt costs at least its entry and exit (12 + 10 cycles).
        assert!(spec(Transfer::Interrupt) >= 22);
    }
}

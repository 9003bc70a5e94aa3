//! The node's seven ports over a board's UARTs.
//!
//! One UART goes to the host; `N` go to neighbours, each serving the port
//! [`node_fw::wiring::uart_ports`] gives it once the node knows where it sits
//! in the array. Bytes move between the UARTs (embedded-io streams, polled
//! without blocking) and the node's reliable channels, through a transmit
//! ring per port so that a frame goes out whole.

use embedded_io::{Read, ReadReady, Write, WriteReady};
use node_fw::Port;
use node_fw::framed::FramedLinks;
use node_fw::wiring::uart_ports;

use crate::board::LostBytes;
use crate::tx_ring::TxRing;

/// Bytes read from one UART per pass, so one busy port cannot starve the rest.
const READ_BURST: usize = 64;

/// A board's UARTs and which port each serves.
pub struct Wires<U, const N: usize> {
    host: U,
    neighbours: [U; N],
    map: [Option<Port>; N],
    /// The array position the map was made for.
    wired_for: Option<([u16; 3], [u16; 3])>,
    tx: [TxRing; 7],
}

impl<U: Read + Write + ReadReady + WriteReady + LostBytes, const N: usize> Wires<U, N> {
    /// A board with a UART for every neighbour port serves them all from
    /// the start, so that it learns who is at the end of each cable before it
    /// knows its place; with fewer, the UARTs wait for the place.
    pub fn new(host: U, neighbours: [U; N]) -> Self {
        let map = Self::fixed().unwrap_or([None; N]);
        Self { host, neighbours, map, wired_for: None, tx: [const { TxRing::new() }; 7] }
    }

    /// UART `i` serving `Port::NEIGHBOURS[i]`, if the board has six.
    fn fixed() -> Option<[Option<Port>; N]> {
        (N >= Port::NEIGHBOURS.len()).then(|| core::array::from_fn(|i| Port::NEIGHBOURS.get(i).copied()))
    }

    /// Maps the neighbour UARTs for a node at `coord` of `array`; the error
    /// names a port the board has no UART for.
    pub fn wire(&mut self, coord: [u16; 3], array: [u16; 3]) -> Result<(), Port> {
        if self.wired_for == Some((coord, array)) {
            return Ok(());
        }
        self.wired_for = Some((coord, array));
        let placed = uart_ports::<N>(coord, array)?;
        self.map = Self::fixed().unwrap_or(placed);
        Ok(())
    }

    /// Feeds what the UARTs received to the node's channels; returns the
    /// number of bytes read.
    pub fn receive<const W: usize, const Q: usize>(&mut self, links: &mut FramedLinks<W, Q>) -> usize {
        let mut read = drain(&mut self.host, Port::Host, links);
        for (uart, port) in self.neighbours.iter_mut().zip(self.map) {
            if let Some(port) = port {
                read += drain(uart, port, links);
            }
        }
        read
    }

    /// Takes the frames due at `now` into the transmit rings and writes what
    /// the UARTs accept; returns the number of bytes written.
    pub fn transmit<const W: usize, const Q: usize>(
        &mut self,
        now: u64,
        links: &mut FramedLinks<W, Q>,
    ) -> usize {
        let map = self.map;
        let tx = &mut self.tx;
        links.transmit(now, |port, bytes| {
            // Frames for a port with no UART stay in the channel (the node
            // reported the missing port already).
            let wired = port == Port::Host || map.contains(&Some(port));
            wired && tx.get_mut(port.index()).is_some_and(|ring| ring.push_frame(bytes))
        });
        let mut written = 0;
        if let Some(ring) = self.tx.get_mut(Port::Host.index()) {
            written += fill(&mut self.host, ring);
        }
        for (uart, port) in self.neighbours.iter_mut().zip(self.map) {
            if let Some(ring) = port.and_then(|p| self.tx.get_mut(p.index())) {
                written += fill(uart, ring);
            }
        }
        written
    }

    /// Whether bytes still wait to be written.
    pub fn sending(&self) -> bool {
        self.tx.iter().any(|r| !r.is_empty())
    }
}

fn drain<U: Read + ReadReady + LostBytes, const W: usize, const Q: usize>(
    uart: &mut U,
    port: Port,
    links: &mut FramedLinks<W, Q>,
) -> usize {
    // Byte by byte, and only while the port's inbox has room: a frame that
    // completes into a full inbox would be dropped and cost a resend. First
    // what is left of a batch the inbox had no room for.
    if links.holds_back(port) {
        links.ingest(port, &[]);
    }
    let mut byte = [0u8; 1];
    let mut read = 0;
    while read < READ_BURST && links.can_ingest(port) && uart.read_ready().unwrap_or(false) {
        match uart.read(&mut byte) {
            Ok(1) => links.ingest(port, &byte),
            _ => break,
        }
        read += 1;
    }
    // The node tells the host of these with its links' other troubles.
    links.note_lost(port, uart.take_lost());
    read
}

/// Writes what the UART takes of `ring`, a run of bytes a call.
fn fill<U: Write + WriteReady>(uart: &mut U, ring: &mut TxRing) -> usize {
    let mut written = 0;
    while !ring.is_empty() && uart.write_ready().unwrap_or(false) {
        match uart.write(ring.front_run()) {
            Ok(n) if n > 0 => {
                ring.consume(n);
                written += n;
            }
            _ => break,
        }
    }
    written
}

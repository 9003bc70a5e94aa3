//! The firmware's main loop: the same sans-IO node as in the simulator,
//! polled with the board's clock over its UARTs.

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write, WriteReady};
use link_proto::{ErrorCode, ErrorReport, Message};
use node_fw::Links;
use node_fw::Port;
use node_fw::wiring::index_of;

use crate::board::LostBytes;
use crate::capacity::{BoardLinks, BoardNode};
use crate::clock::Clock;
use crate::lights::{Activity, Lights};
use crate::wires::Wires;

/// How long a channel waits without an acknowledgement before it resends.
///
/// A real board's round trip is well under a millisecond, so this only
/// bounds how soon a lost frame is noticed; the receiver's nak recovers a
/// gap at once whenever a later frame arrives. Emulated boards need the
/// margin: they idle in real time, and twenty-seven emulators on two cores
/// leave a peer unscheduled for tens of milliseconds. At 20 ms the 3x3x3
/// netduinoplus2 frame of docs/boards.md took 402 s with 4 333 resends
/// (each one more work for the starved peers); at 200 ms, 8-11 s with
/// 210-484.
pub const RESEND_AFTER_MS: u64 = 200;

/// [`RESEND_AFTER_MS`] in `clock`'s ticks.
pub fn resend_after(clock: &impl Clock) -> u64 {
    clock.ticks_per_second() / 1000 * RESEND_AFTER_MS
}

/// How the loop waits when there is nothing to do.
#[derive(Debug, Clone, Copy)]
pub struct Idle {
    /// Forgets pended wake-ups (called before each poll).
    pub clear: fn(),
    /// Waits until something pends.
    pub sleep: fn(),
}

/// Runs the node for ever, sleeping whenever a pass finds nothing to do;
/// the lights show which.
pub fn run<U, W, F, const N: usize>(
    node: &mut BoardNode,
    links: &mut BoardLinks,
    wires: &mut Wires<U, N>,
    clock: &mut impl Clock,
    lights: &mut Lights<W, F>,
    idle: Idle,
) -> !
where
    U: Read + Write + ReadReady + WriteReady + LostBytes,
    W: OutputPin,
    F: OutputPin,
{
    let mut told = Told::default();
    loop {
        (idle.clear)();
        let busy = step(node, links, wires, clock.now());
        told.update(node);
        lights.show(match (node.failed(), busy) {
            (true, _) => Activity::Failed,
            (false, true) => Activity::Running,
            (false, false) => Activity::Waiting,
        });
        if !busy {
            // Nothing arrived, nothing was sent, the node did no work: only
            // a byte or the wake-up timer can change that.
            (idle.sleep)();
        }
    }
}

/// What the bring-up log has said (a real board's only).
#[derive(Default)]
struct Told {
    #[cfg(feature = "stm32f413")]
    peers: [Option<link_proto::BoardId>; 6],
    #[cfg(feature = "stm32f413")]
    failed: bool,
}

impl Told {
    /// Logs what changed since the last pass.
    #[cfg(feature = "stm32f413")]
    fn update(&mut self, node: &BoardNode) {
        for (port, (told, now)) in self.peers.iter_mut().zip(node.peers()).enumerate() {
            if let Some(id) = now.filter(|_| *told != now) {
                crate::log::peer(port, id);
                *told = now;
            }
        }
        if node.failed() && !self.failed {
            crate::log::failed();
            self.failed = true;
        }
    }

    /// Emulated boards log nothing.
    #[cfg(not(feature = "stm32f413"))]
    fn update(&mut self, _node: &BoardNode) {}
}

/// One pass: bytes in, one node poll, bytes out. Returns whether anything
/// happened.
pub fn step<U, const N: usize>(
    node: &mut BoardNode,
    links: &mut BoardLinks,
    wires: &mut Wires<U, N>,
    now: u64,
) -> bool
where
    U: Read + Write + ReadReady + WriteReady + LostBytes,
{
    let read = wires.receive(links);
    let work = node.poll(now, links);
    if let Some(a) = node.assignment()
        && let Err(port) = wires.wire(a.coord, a.array)
    {
        // The host asked for an array this board cannot be cabled into.
        let node_id = index_of(a.coord, a.array).unwrap_or(u16::MAX);
        let report =
            ErrorReport { node: node_id, code: ErrorCode::PortCapacity, a: port as u32, b: N as u32 };
        let _ = links.try_send(Port::Host, Message::Error(report));
    }
    let written = wires.transmit(now, links);
    read > 0 || written > 0 || work.is_busy() || wires.sending()
}

//! Joins the neighbour UARTs of emulated boards: every byte one board's UART
//! sends on a link reaches the other end, in order, whatever the other
//! emulator is doing.
//!
//! Each emulator connects each of its link UARTs to a socket of the relay.
//! One thread polls them all: it reads whatever arrives at once (so a sending
//! emulator never waits on its peer) and writes it on as fast as the peer
//! takes it, queueing the rest without bound. Two boards that write to each
//! other at once then cannot stall each other, as STM32 boards joined socket
//! to socket do. One thread, rather than one per direction, keeps a byte's
//! trip to one wake-up on a machine whose cores the emulators keep busy.

use std::collections::{BTreeMap, VecDeque};
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use mio::{Events, Interest, Poll, Token};
use node_fw::Port;
use sim_board::{Faults, FaultyStream};

use crate::error::HostError;

/// A link: the lower node, its port, the higher node.
pub type LinkKey = (usize, Port, usize);

/// How often the relay looks at its stop flag.
const STOP_CHECK: Duration = Duration::from_millis(50);

/// One end of a link, waiting for its emulator to connect.
struct End {
    node: usize,
    port: Port,
    listener: UnixListener,
}

/// Bytes relayed from each node, per port.
type Counters = Arc<Vec<[AtomicU64; 7]>>;

/// The relay of an array of emulated boards; it stops when dropped.
#[derive(Default)]
pub struct Relay {
    pending: BTreeMap<LinkKey, Vec<End>>,
    /// Faults on every byte stream the relay carries.
    faults: Option<Faults>,
    counters: Counters,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// A connected end: its socket, the peer end it relays to, what waits to be
/// written into it, and where its bytes are counted.
struct Socket {
    stream: mio::net::UnixStream,
    peer: usize,
    queue: VecDeque<u8>,
    /// The faults dealt to what this end sends.
    faults: Option<FaultyStream>,
    node: usize,
    port: Port,
    open: bool,
    writable_wanted: bool,
}

impl Relay {
    /// A relay with no links yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// A relay that deals `faults` to the frames it carries, on every link
    /// end's stream its own.
    pub fn with_faults(faults: Option<Faults>) -> Self {
        let mut relay = Self::default();
        relay.faults = faults;
        relay
    }

    /// Adds the end of `link` at `node`'s `port`, whose emulator will
    /// connect to `listener`.
    pub fn end(&mut self, link: LinkKey, node: usize, port: Port, listener: UnixListener) {
        self.pending.entry(link).or_default().push(End { node, port, listener });
    }

    /// Waits up to `timeout` for every end to connect, then relays every
    /// link both ways until the relay is dropped.
    pub fn join(&mut self, timeout: Duration) -> Result<(), HostError> {
        let nodes = self.pending.values().flatten().map(|e| e.node + 1).max().unwrap_or(0);
        self.counters = Arc::new((0..nodes).map(|_| std::array::from_fn(|_| AtomicU64::new(0))).collect());
        let deadline = Instant::now() + timeout;
        let mut sockets = Vec::new();
        for (link, ends) in std::mem::take(&mut self.pending) {
            let [a, b] = <[End; 2]>::try_from(ends).map_err(|ends| {
                HostError::Node(format!("link {link:?} has {} ends; a link joins two", ends.len()))
            })?;
            let first = sockets.len();
            for (end, peer) in [(a, first + 1), (b, first)] {
                let stream = accept(&end, deadline, timeout)?;
                sockets.push(Socket {
                    stream: mio::net::UnixStream::from_std(stream),
                    peer,
                    queue: VecDeque::new(),
                    faults: self.faults.map(|f| FaultyStream::new(f, end.node, end.port.index())),
                    node: end.node,
                    port: end.port,
                    open: true,
                    writable_wanted: false,
                });
            }
        }
        let poll = Poll::new().map_err(|e| HostError::Io(format!("relay poll: {e}")))?;
        for (i, s) in sockets.iter_mut().enumerate() {
            poll.registry()
                .register(&mut s.stream, Token(i), Interest::READABLE)
                .map_err(|e| HostError::Io(format!("relay poll: {e}")))?;
        }
        let (stop, counters) = (Arc::clone(&self.stop), Arc::clone(&self.counters));
        self.thread = Some(std::thread::spawn(move || relay(poll, sockets, &stop, &counters)));
        Ok(())
    }

    /// Bytes relayed from `node`, per port (port order).
    pub fn bytes_from(&self, node: usize) -> [u64; 7] {
        self.counters.get(node).map_or([0; 7], |c| std::array::from_fn(|i| c[i].load(Ordering::Relaxed)))
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The relay's loop: until `stop`, move what each socket reads into its
/// peer's queue and write queues out as far as each peer takes them.
fn relay(mut poll: Poll, mut sockets: Vec<Socket>, stop: &AtomicBool, counters: &Counters) {
    let mut events = Events::with_capacity(sockets.len().max(1) * 2);
    let mut buf = vec![0u8; 1 << 16];
    while !stop.load(Ordering::Relaxed) && sockets.iter().any(|s| s.open) {
        if poll.poll(&mut events, Some(STOP_CHECK)).is_err() {
            continue;
        }
        let mut touched = Vec::new();
        for event in &events {
            let i = event.token().0;
            if event.is_readable() || event.is_read_closed() {
                read_all(&mut sockets, i, &mut buf, counters);
                if let Some(peer) = sockets.get(i).map(|s| s.peer) {
                    touched.push(peer);
                }
            }
            if event.is_writable() {
                touched.push(i);
            }
        }
        for i in touched {
            flush(&mut sockets, i, &poll);
        }
    }
}

/// Reads everything socket `i` has into its peer's queue (edge-triggered
/// polling reports a socket once until it is drained).
fn read_all(sockets: &mut [Socket], i: usize, buf: &mut [u8], counters: &Counters) {
    loop {
        let Some(s) = sockets.get_mut(i) else { return };
        let n = match s.stream.read(buf) {
            Ok(0) => {
                s.open = false;
                return;
            }
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) if e.kind() == ErrorKind::WouldBlock => return,
            Err(_) => {
                s.open = false;
                return;
            }
        };
        if let Some(c) = counters.get(s.node).and_then(|c| c.get(s.port.index())) {
            c.fetch_add(n as u64, Ordering::Relaxed);
        }
        let peer = s.peer;
        let Some(bytes) = buf.get(..n) else { return };
        let mut faults = s.faults.take();
        if let Some(p) = sockets.get_mut(peer) {
            match faults.as_mut() {
                Some(f) => f.pass(bytes, &mut p.queue),
                None => p.queue.extend(bytes),
            }
        }
        if let Some(s) = sockets.get_mut(i) {
            s.faults = faults;
        }
    }
}

/// Writes socket `i`'s queue until it is empty or the socket is full, and
/// asks to hear when it can take more only while something waits.
fn flush(sockets: &mut [Socket], i: usize, poll: &Poll) {
    let Some(s) = sockets.get_mut(i) else { return };
    while !s.queue.is_empty() && s.open {
        let (front, _) = s.queue.as_slices();
        match s.stream.write(front) {
            Ok(n) => {
                s.queue.drain(..n);
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) if e.kind() == ErrorKind::WouldBlock => break,
            Err(_) => s.open = false,
        }
    }
    let want = !s.queue.is_empty() && s.open;
    if want != s.writable_wanted {
        let interest = if want { Interest::READABLE | Interest::WRITABLE } else { Interest::READABLE };
        if poll.registry().reregister(&mut s.stream, Token(i), interest).is_ok() {
            s.writable_wanted = want;
        }
    }
}

/// Accepts the emulator's connection to `end` before `deadline`, as a
/// non-blocking stream.
fn accept(end: &End, deadline: Instant, timeout: Duration) -> Result<UnixStream, HostError> {
    let io =
        |e: std::io::Error| HostError::Io(format!("link socket of node {} {:?}: {e}", end.node, end.port));
    end.listener.set_nonblocking(true).map_err(io)?;
    loop {
        match end.listener.accept() {
            Ok((stream, _)) => {
                stream.set_nonblocking(true).map_err(io)?;
                return Ok(stream);
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                return Err(HostError::Node(format!(
                    "the emulator of node {} did not connect its {:?} link within {} s",
                    end.node,
                    end.port,
                    timeout.as_secs()
                )));
            }
            Err(e) => return Err(io(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pattern that shows order: byte `i` of a stream is `i * k mod 251`.
    fn pattern(len: usize, k: usize) -> Vec<u8> {
        (0..len).map(|i| (i * k % 251) as u8).collect()
    }

    /// A relay of the link `key` between its two listening ends, and their
    /// socket paths (in `dir`).
    fn link(dir: &std::path::Path, key: LinkKey) -> (Relay, [std::path::PathBuf; 2]) {
        faulty_link(dir, key, None)
    }

    /// [`link`], dealing `faults`.
    fn faulty_link(
        dir: &std::path::Path,
        key: LinkKey,
        faults: Option<Faults>,
    ) -> (Relay, [std::path::PathBuf; 2]) {
        let (lo, port, hi) = key;
        let paths = [dir.join("a.sock"), dir.join("b.sock")];
        let mut relay = Relay::with_faults(faults);
        relay.end(key, lo, port, UnixListener::bind(&paths[0]).expect("bind a"));
        relay.end(key, hi, port.opposite(), UnixListener::bind(&paths[1]).expect("bind b"));
        (relay, paths)
    }

    #[test]
    fn two_ends_that_write_at_once_without_reading_both_get_everything_in_order() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let (mut relay, [pa, pb]) = link(dir.path(), (0, Port::PosX, 1));
        let (mut a, mut b) = (UnixStream::connect(&pa).expect("a"), UnixStream::connect(&pb).expect("b"));
        relay.join(Duration::from_secs(5)).expect("both ends connect");

        // Each end writes far more than the sockets between them hold
        // (about 200 KiB each way) before it reads anything, as two blocked
        // emulators would: joined directly, both writes would never finish.
        const LEN: usize = 4 << 20;
        let (from_a, from_b) = (pattern(LEN, 7), pattern(LEN, 13));
        let writer = |mut s: UnixStream, data: Vec<u8>| std::thread::spawn(move || s.write_all(&data));
        let wa = writer(a.try_clone().expect("clone"), from_a.clone());
        let wb = writer(b.try_clone().expect("clone"), from_b.clone());
        wa.join().expect("writer a").expect("a's write finishes before anyone reads");
        wb.join().expect("writer b").expect("b's write finishes before anyone reads");

        let (mut at_a, mut at_b) = (vec![0u8; LEN], vec![0u8; LEN]);
        b.read_exact(&mut at_b).expect("b reads all a wrote");
        a.read_exact(&mut at_a).expect("a reads all b wrote");
        assert!(at_b == from_a, "a's bytes reached b in order");
        assert!(at_a == from_b, "b's bytes reached a in order");
        assert_eq!(relay.bytes_from(0)[Port::PosX.index()], LEN as u64);
        assert_eq!(relay.bytes_from(1)[Port::NegX.index()], LEN as u64);
    }

    #[test]
    fn a_faulty_relay_drops_whole_frames_and_keeps_the_rest_in_order() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let faults = Faults { drop: 0.5, seed: 9, ..Faults::default() };
        let (mut relay, [pa, pb]) = faulty_link(dir.path(), (0, Port::PosZ, 1), Some(faults));
        let (mut a, mut b) = (UnixStream::connect(&pa).expect("a"), UnixStream::connect(&pb).expect("b"));
        relay.join(Duration::from_secs(5)).expect("both ends connect");
        // 100 frames of four bytes: the relay passes each whole or not at all.
        let frames: Vec<u8> = (1..=100u8).flat_map(|i| [0, i, i, i, i, 0]).collect();
        a.write_all(&frames).expect("written");
        let mut got = Vec::new();
        b.set_read_timeout(Some(Duration::from_millis(500))).expect("timeout");
        let mut buf = [0u8; 1024];
        while let Ok(n) = b.read(&mut buf) {
            if n == 0 {
                break;
            }
            got.extend_from_slice(&buf[..n]);
        }
        let kept: Vec<u8> = got.split(|&x| x == 0).filter(|f| !f.is_empty()).map(|f| f[0]).collect();
        assert!(kept.len() > 25 && kept.len() < 75, "{} of 100 frames passed", kept.len());
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "in order");
        assert!(got.split(|&x| x == 0).all(|f| f.is_empty() || f.len() == 4), "whole frames");
    }

    #[test]
    fn an_end_that_never_connects_is_named() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let (mut relay, [pa, _]) = link(dir.path(), (2, Port::PosY, 5));
        let _a = UnixStream::connect(&pa).expect("a");
        let err = relay.join(Duration::from_millis(200)).expect_err("b never connects");
        assert!(err.to_string().contains("node 5") && err.to_string().contains("NegY"), "{err}");
    }
}

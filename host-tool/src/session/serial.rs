//! Boards over serial links: one serial device per node (a pty of an emulated
//! board, or a USB-serial adapter of a real one).
//!
//! Each device carries CRC-checked frames through the same go-back-N channel
//! the nodes run ([`node_fw::reliable::Channel`]), so a lost or damaged byte
//! costs a resend, never a message. Every node must say hello first (its
//! protocol version and capacities). While a render runs, the host sends a
//! hello now and then as a heartbeat: a node that leaves our frames
//! unacknowledged for the time-out has stopped answering, and the run ends
//! naming it instead of hanging.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use link_proto::{BoardId, BoardInfo, Capacity, Hello, Message, PROTOCOL_VERSION};
use node_fw::Port;
use node_fw::reliable::{Channel, ChannelStats};
use serialport::SerialPort;
use sim_board::{Faults, FaultyStream};

use crate::error::HostError;
use crate::session::cabling::{self, Reported};
use crate::session::clock::HostMicros;
use crate::session::transport::{Endpoint, RunEnd, Transport};

/// Unacknowledged frames per node link on the host's side: as the nodes keep.
const WINDOW: usize = node_fw::reliable::WINDOW;
/// Microseconds without an acknowledgement before the host resends.
const RESEND_AFTER_US: u64 = 250_000;
/// Bytes the host queues per device beyond what the device took.
const TX_QUEUE: usize = 4096;
/// Heartbeat period while waiting.
const HEARTBEAT: Duration = Duration::from_millis(500);
/// Node time-outs without a retired ray, or another message that shows the
/// frame moving, after which a run that every node still answers fails.
const STALL_TIMEOUTS: u32 = 3;
/// How long the boards get to report who is at the end of each cable.
const CABLING_WAIT: Duration = Duration::from_secs(5);
/// Baud rate for real devices: the NUCLEO-F413ZH image's host link (ptys
/// ignore it).
pub const BAUD: u32 = clock_tree::nucleo_f413zh::HOST_BAUD;

/// One node's serial link.
struct Link {
    name: String,
    port: Box<dyn SerialPort>,
    channel: Channel<WINDOW>,
    /// Messages waiting for room in the channel's window.
    outbox: VecDeque<Message>,
    hello: Option<Hello>,
    /// The board at each neighbour port of this link's board, as it told us.
    peers: [Option<BoardId>; 6],
    bytes_sent: u64,
    /// Frames written into the device only in part or not yet (never blocks).
    unsent: VecDeque<u8>,
    /// Faults dealt to what the node sends and to what the host sends.
    faults: Option<(FaultyStream, FaultyStream)>,
}

/// The array as seen through serial devices, node `i` on device `i`.
pub struct SerialArray {
    links: Vec<Link>,
    started: Instant,
    timeout: Duration,
    /// Hellos taken while connecting, handed to the first run's host.
    greeted: Vec<(u16, Message)>,
    last_heartbeat: Instant,
    /// Names of the nodes (their coordinates), for errors.
    names: Vec<String>,
    /// Whether the map of occupied cubes follows a frame's start
    /// ([`Transport::map_follows_start`]): not on QEMU's boards.
    map_follows_start: bool,
}

impl SerialArray {
    /// Opens one device per node; `names` label the nodes in errors.
    pub fn open(paths: &[String], names: Vec<String>, timeout: Duration) -> Result<Self, HostError> {
        let incarnation = host_incarnation();
        let links = paths.iter().map(|p| open_link(p, incarnation)).collect::<Result<Vec<_>, _>>()?;
        let now = Instant::now();
        Ok(Self {
            links,
            started: now,
            timeout,
            greeted: Vec::new(),
            last_heartbeat: now,
            names,
            map_follows_start: true,
        })
    }

    /// Boards that take the host's bytes only while idle (QEMU's): each
    /// frame's map of occupied cubes goes before its start.
    pub fn map_first(mut self) -> Self {
        self.map_follows_start = false;
        self
    }

    /// Deals `faults` to every frame on the host links, both ways, each
    /// direction of each link its own stream (no faults when `None`).
    pub fn with_faults(mut self, faults: Option<Faults>) -> Self {
        for (i, link) in self.links.iter_mut().enumerate() {
            link.faults = faults.map(|f| {
                (FaultyStream::new(f, i, Port::Host.index()), FaultyStream::new(f, i, Port::Host.index() + 1))
            });
        }
        self
    }

    /// Waits until every node has said hello; checks versions.
    pub fn connect(&mut self) -> Result<(), HostError> {
        for i in 0..self.links.len() {
            self.send(i, Message::Hello(Hello::host()));
        }
        let deadline = Instant::now() + self.timeout;
        while self.links.iter().any(|l| l.hello.is_none()) {
            if Instant::now() > deadline {
                let silent = self.links.iter().position(|l| l.hello.is_none()).unwrap_or(0);
                let damaged = self.links[silent].channel.stats.corrupted;
                // Frames of another protocol's framing fail the check before
                // any hello could say which version the board speaks.
                let why = if damaged > 0 {
                    format!(
                        "; {damaged} frames from it failed their check: flash it with this version's firmware (protocol {})",
                        link_proto::PROTOCOL_VERSION
                    )
                } else {
                    String::new()
                };
                return Err(HostError::Node(format!(
                    "{} on {} did not say hello within {:.0?}{why}",
                    self.name(silent),
                    self.links[silent].name,
                    self.timeout
                )));
            }
            self.pump_and_note()?;
        }
        Ok(())
    }

    /// One pass of [`Self::pump`] before a run: hellos and peer notes are
    /// noted, everything is kept for the run's host.
    fn pump_and_note(&mut self) -> Result<bool, HostError> {
        let mut got = Vec::new();
        let moved = self.pump(&mut |node, _, msg| got.push((node, msg)))?;
        for (node, msg) in got {
            let i = usize::from(node);
            match &msg {
                Message::Hello(h) if h.version != PROTOCOL_VERSION => {
                    return Err(HostError::Version(format!(
                        "{} on {} speaks protocol version {}, the host {PROTOCOL_VERSION}",
                        self.name(i),
                        self.links[i].name,
                        h.version
                    )));
                }
                Message::Hello(h) => self.links[i].hello = Some(*h),
                Message::Peer(note) => {
                    if let Some(peer) = self.links[i].peers.get_mut(usize::from(note.port)) {
                        *peer = Some(note.board);
                    }
                }
                _ => {}
            }
            self.greeted.push((node, msg));
        }
        Ok(moved)
    }

    /// What each device's board has told about itself and its cables.
    pub fn reported(&self) -> Vec<Reported> {
        self.links
            .iter()
            .map(|l| Reported {
                device: l.name.clone(),
                board: l.hello.map_or(BoardInfo::HOST, |h| h.board),
                peers: l.peers,
            })
            .collect()
    }

    /// The hellos, in device order (after [`Self::connect`]).
    pub fn hellos(&self) -> Vec<Option<Hello>> {
        self.links.iter().map(|l| l.hello).collect()
    }

    /// Moves messages until `enough` holds of what the boards reported, or
    /// `wait` has passed.
    pub fn gather(&mut self, wait: Duration, enough: impl Fn(&[Reported]) -> bool) -> Result<(), HostError> {
        let deadline = Instant::now() + wait;
        while !enough(&self.reported()) && Instant::now() < deadline {
            if !self.pump_and_note()? {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        Ok(())
    }

    /// Whether every board serves fixed ports, so its cables can be checked
    /// before it knows its place ([`link_proto::BoardKind::fixed_ports`]).
    fn fixed_ports(&self) -> bool {
        self.links.iter().all(|l| l.hello.is_some_and(|h| h.board.kind.fixed_ports()))
    }

    /// Checks that node `i`'s board, on device `i`, is cabled to its
    /// neighbours in `array`; the error names a crossed, missing or swapped
    /// cable, or says in which order the devices are cabled. Boards that wire
    /// their UARTs from their place in the array (mps2-an385) pass unchecked.
    pub fn check_cabling(&mut self, array: [u16; 3]) -> Result<(), HostError> {
        if !self.fixed_ports() {
            return Ok(());
        }
        if let Some(l) = self.links.iter().find(|l| !l.hello.is_some_and(|h| h.board.id.is_known())) {
            eprintln!("warning: the board on {} has no unique id, so the cables go unchecked", l.name);
            return Ok(());
        }
        self.gather(CABLING_WAIT, |r| cabling::complete(r, array))?;
        let reported = self.reported();
        let faults = cabling::check(&reported, array);
        let Some(first) = faults.first() else { return Ok(()) };
        if let Ok(order) = cabling::order(&reported, array) {
            let devices: Vec<&str> = order.iter().map(|&d| reported[d].device.as_str()).collect();
            return Err(HostError::Cabling(format!(
                "the boards are cabled as a {}x{}x{} array, but --ports lists them in another order; \
                 in array order: --ports {} (or add --order-ports)",
                array[0],
                array[1],
                array[2],
                devices.join(",")
            )));
        }
        let more = match faults.len() {
            1 => String::new(),
            n => format!(" (and {} more)", n - 1),
        };
        Err(HostError::Cabling(format!("{}{more}", cabling::describe(first, &reported, array))))
    }

    /// Puts the devices in array order, read from the cabling; returns them
    /// in that order.
    pub fn order_by_cabling(&mut self, array: [u16; 3]) -> Result<Vec<String>, HostError> {
        if !self.fixed_ports() {
            return Err(HostError::Cabling(
                "these boards map their UARTs from their place in the array, so their cables cannot be \
                 read before it: list --ports in array order"
                    .into(),
            ));
        }
        self.gather(CABLING_WAIT, |r| cabling::order(r, array).is_ok())?;
        let order = cabling::order(&self.reported(), array)
            .map_err(|why| HostError::Cabling(format!("no array order fits the cabling: {why}")))?;
        let mut links: Vec<Option<Link>> = std::mem::take(&mut self.links).into_iter().map(Some).collect();
        self.links = order.iter().filter_map(|&d| links.get_mut(d).and_then(Option::take)).collect();
        // Messages already taken belong to the devices' new places.
        let place = |d: u16| order.iter().position(|&o| o == usize::from(d)).map_or(d, |p| p as u16);
        for (node, _) in &mut self.greeted {
            *node = place(*node);
        }
        Ok(self.links.iter().map(|l| l.name.clone()).collect())
    }

    /// One pass over the devices: read, deliver (with the host's time in
    /// microseconds), write. Returns whether any byte moved.
    fn pump(&mut self, deliver: &mut dyn FnMut(u16, HostMicros, Message)) -> Result<bool, HostError> {
        let now = self.micros();
        let mut moved = false;
        let names = &self.names;
        for (i, link) in self.links.iter_mut().enumerate() {
            // A device that closes (a board unplugged or reset, a relay gone)
            // ends the run naming its node.
            let closed = |e: std::io::Error, link: &Link| {
                let node = names.get(i).cloned().unwrap_or_else(|| format!("node {i}"));
                HostError::Node(format!("{node} on {}: the link closed ({e}); no image written", link.name))
            };
            let mut bytes = read_available(link).map_err(|e| closed(e, link))?;
            moved |= !bytes.is_empty();
            if let Some((inbound, _)) = link.faults.as_mut() {
                let mut dealt = Vec::with_capacity(bytes.len());
                inbound.pass(&bytes, &mut dealt);
                bytes = dealt;
            }
            let mut got = Vec::new();
            link.channel.receive(&bytes, |m| {
                got.push(m);
                true
            });
            for m in got {
                deliver(i as u16, now, m);
            }
            while link.channel.can_send() {
                let Some(m) = link.outbox.pop_front() else { break };
                if let Err(m) = link.channel.send(m) {
                    link.outbox.push_front(m);
                    break;
                }
            }
            let (unsent, faults) = (&mut link.unsent, &mut link.faults);
            link.channel.transmit(now.0, |frame| {
                let room = unsent.len() + frame.len() <= TX_QUEUE;
                match faults.as_mut() {
                    Some((_, outbound)) if room => outbound.pass(frame, unsent),
                    _ if room => unsent.extend(frame),
                    _ => {}
                }
                room
            });
            moved |= flush(link).map_err(|e| closed(e, link))?;
        }
        Ok(moved)
    }

    /// A hello to every node with nothing in flight, so that each owes an ack.
    fn heartbeat(&mut self) {
        if self.last_heartbeat.elapsed() < HEARTBEAT {
            return;
        }
        self.last_heartbeat = Instant::now();
        for link in &mut self.links {
            if !link.channel.busy() && link.outbox.is_empty() {
                link.outbox.push_back(Message::Hello(Hello::host()));
            }
        }
    }

    /// Fails naming the node silent longest, once that is over the time-out
    /// (after a stall of the host itself, every node looks silent; the one
    /// that stopped first is the one to blame).
    fn check_alive(&self) -> Result<(), HostError> {
        let now = self.micros();
        let silence = |l: &Link| l.channel.unanswered_for(now.0);
        let Some((i, link)) = self.links.iter().enumerate().max_by_key(|(_, l)| silence(l)) else {
            return Ok(());
        };
        let silent = Duration::from_micros(silence(link));
        if silent > self.timeout {
            return Err(HostError::Node(format!(
                "{} on {} stopped answering: no acknowledgement for {:.1} s",
                self.name(i),
                link.name,
                silent.as_secs_f64()
            )));
        }
        Ok(())
    }

    fn name(&self, i: usize) -> String {
        self.names.get(i).cloned().unwrap_or_else(|| format!("node {i}"))
    }

    fn micros(&self) -> HostMicros {
        HostMicros(self.started.elapsed().as_micros() as u64)
    }
}

impl Transport for SerialArray {
    type Time = HostMicros;

    /// The smallest capacity over the nodes.
    fn capacity(&self) -> Capacity {
        let caps = self.links.iter().filter_map(|l| l.hello.map(|h| h.capacity));
        caps.reduce(|a, b| Capacity {
            spheres: a.spheres.min(b.spheres),
            refs: a.refs.min(b.refs),
            cubes: a.cubes.min(b.cubes),
            rays: a.rays.min(b.rays),
        })
        .unwrap_or(Capacity { spheres: 0, refs: 0, cubes: 0, rays: 0 })
    }

    fn nodes(&self) -> usize {
        self.links.len()
    }

    /// Queues a message for node `node`.
    fn send(&mut self, node: usize, msg: Message) {
        if let Some(link) = self.links.get_mut(node) {
            link.outbox.push_back(msg);
        }
    }

    fn bytes_sent(&self, node: usize) -> [u64; 7] {
        // The host sees only its own link to each node.
        [0, 0, 0, 0, 0, 0, self.links.get(node).map_or(0, |l| l.bytes_sent)]
    }

    /// Resends and damaged frames on the host's side of the links.
    fn map_follows_start(&self) -> bool {
        self.map_follows_start
    }

    fn link_stats(&self) -> ChannelStats {
        self.links.iter().map(|l| l.channel.stats).sum()
    }

    /// Moves messages until `host` is finished; fails naming a node that
    /// stops answering.
    fn run(&mut self, host: &mut impl Endpoint<HostMicros>) -> Result<RunEnd<HostMicros>, HostError> {
        let start = self.micros();
        for (node, msg) in std::mem::take(&mut self.greeted) {
            host.receive(node, start, msg);
        }
        let mut rounds = 0;
        let mut progress = Instant::now();
        while !host.finished() {
            rounds += 1;
            let moved = self.pump(&mut |node, at, msg| {
                if sim_board::progresses(&msg) {
                    progress = Instant::now();
                }
                host.receive(node, at, msg)
            })?;
            self.heartbeat();
            self.check_alive()?;
            // Nodes that answer every frame but return nothing: an array that
            // lost its way (a firmware fault) would otherwise hold the host for ever.
            let stalled = progress.elapsed();
            if stalled > STALL_TIMEOUTS * self.timeout {
                return Err(HostError::Node(format!(
                    "the array stopped making progress: every node answers, but nothing has come back \
                     for {:.0} s (3 x --node-timeout); no image written",
                    stalled.as_secs_f64()
                )));
            }
            if !moved {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        // Let the last acknowledgements out so the nodes' windows drain.
        self.pump(&mut |_, _, _| {})?;
        Ok(RunEnd { start, end: self.micros(), rounds })
    }
}

/// This host run's incarnation on its links: boards still running from an
/// earlier run see a new one, drop that run's state and say hello again.
/// One for all links: it names the session, and neighbours of one session
/// take each other's messages only ([`node_fw::Links::session`]).
fn host_incarnation() -> u32 {
    let nanos =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u32);
    nanos ^ std::process::id().rotate_left(16)
}

fn open_link(path: &str, incarnation: u32) -> Result<Link, HostError> {
    let port = serialport::new(path, BAUD).timeout(Duration::ZERO).open().map_err(|e| {
        let why = match e.kind {
            serialport::ErrorKind::NoDevice => "is missing".to_string(),
            serialport::ErrorKind::Io(ErrorKind::NotFound) => "is missing".to_string(),
            serialport::ErrorKind::Io(ErrorKind::ResourceBusy) => {
                "is busy (another program has it open)".into()
            }
            _ => format!("cannot be opened: {}", e.description),
        };
        HostError::Serial(format!("serial device {path} {why}"))
    })?;
    let mut channel = Channel::new(RESEND_AFTER_US);
    channel.set_incarnation(incarnation);
    Ok(Link {
        name: path.to_string(),
        port,
        channel,
        outbox: VecDeque::new(),
        hello: None,
        peers: [None; 6],
        faults: None,
        bytes_sent: 0,
        unsent: VecDeque::new(),
    })
}

/// Writes what the device takes now; returns whether it took anything.
fn flush(link: &mut Link) -> std::io::Result<bool> {
    if link.unsent.is_empty() {
        return Ok(false);
    }
    match link.port.write(link.unsent.make_contiguous()) {
        Ok(n) => {
            link.unsent.drain(..n);
            link.bytes_sent += n as u64;
            Ok(n > 0)
        }
        Err(e)
            if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) =>
        {
            Ok(false)
        }
        Err(e) => Err(e),
    }
}

/// The bytes the device holds now (none if it holds none). The device's
/// time-out is zero, so a read polls once and returns at once: with nothing
/// waiting it times out, and on a device whose other end has gone (a board
/// unplugged, an emulator ended) the poll sees the hang-up and the read
/// fails, so the run ends naming the node instead of waiting out the
/// time-out.
fn read_available(link: &mut Link) -> std::io::Result<Vec<u8>> {
    // On the stack: most passes find nothing, and need no allocation.
    let mut buf = [0u8; 4096];
    match link.port.read(&mut buf) {
        Ok(n) => Ok(buf.get(..n).unwrap_or_default().to_vec()),
        Err(e)
            if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) =>
        {
            Ok(Vec::new())
        }
        Err(e) => Err(e),
    }
}

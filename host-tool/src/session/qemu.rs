//! An array of emulated boards: one QEMU instance per node, each joined to
//! the host over a pty, their neighbour UARTs joined through a relay that
//! host-tool owns.
//!
//! Node `i` runs the node firmware; its host UART is a pty the host opens as
//! a serial device. Each neighbour UART is a Unix socket that QEMU connects
//! to and the [`relay`](crate::session::relay) reads from and writes to. Some emulated
//! UARTs (the STM32 ones) block the emulator while a write cannot be
//! delivered, so two boards wired socket to socket that write to each other
//! at once would stall for ever; the relay always reads, and buffers what the
//! other end is not yet taking. Every instance runs with `-icount shift=0`,
//! so its clock counts instructions. The instances are stopped when the
//! array is dropped.

use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use link_proto::BoardId;
use node_fw::Port;
use node_fw::wiring::{coord_of, index_of, uart_ports};
use sim_board::Faults;

use crate::error::{HostError, input};
use crate::session::relay::Relay;

/// The QEMU binary.
pub const QEMU: &str = "qemu-system-arm";
/// How long the emulators get to start and connect.
const START_TIMEOUT: Duration = Duration::from_secs(20);

/// A board QEMU emulates that the node firmware is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EmulatedBoard {
    /// ARM's mps2-an385 (Cortex-M3, five UARTs): the small-MCU image.
    #[default]
    Mps2An385,
    /// The netduinoplus2 (an STM32F405 model with the F413's seven
    /// U(S)ARTs): the STM32 image, built with the emulated SoC's RAM.
    Netduinoplus2,
}

/// What one `-serial` of an instance carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Serial {
    Host,
    Neighbour(Port),
    Unused,
}

impl EmulatedBoard {
    /// Every board, for help texts and tests.
    pub const ALL: [EmulatedBoard; 2] = [EmulatedBoard::Mps2An385, EmulatedBoard::Netduinoplus2];

    /// The QEMU machine name, also the board's name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            EmulatedBoard::Mps2An385 => "mps2-an385",
            EmulatedBoard::Netduinoplus2 => "netduinoplus2",
        }
    }

    /// Neighbour UARTs of the board.
    pub const fn neighbour_uarts(self) -> usize {
        match self {
            EmulatedBoard::Mps2An385 => 4,
            EmulatedBoard::Netduinoplus2 => 6,
        }
    }

    /// The firmware image `scripts/firmware.sh` builds for the board,
    /// found from wherever host-tool runs: beside its own target directory,
    /// else in the source tree it was built from.
    pub fn default_firmware(self) -> PathBuf {
        let file = format!("node-{}.elf", self.name());
        let beside_exe = std::env::current_exe()
            .ok()
            .and_then(|exe| exe.parent()?.parent().map(|target| target.join("firmware").join(&file)));
        let in_tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/firmware").join(&file);
        beside_exe.filter(|p| p.is_file()).unwrap_or(in_tree)
    }

    /// What each `-serial` carries for the node at `coord` of `array`, in
    /// QEMU's order, or the first port the board has no UART for.
    fn serials(self, coord: [u16; 3], array: [u16; 3]) -> Result<Vec<Serial>, Port> {
        let as_serial = |p: Option<Port>| p.map_or(Serial::Unused, Serial::Neighbour);
        match self {
            // UART 0 is the host's; UARTs 1-4 serve the ports that exist.
            EmulatedBoard::Mps2An385 => {
                let map = uart_ports::<4>(coord, array)?;
                Ok(std::iter::once(Serial::Host).chain(map.map(as_serial)).collect())
            }
            // QEMU binds `-serial` to the U(S)ARTs in address order: USART1
            // (+X), USART2 (-X), USART3 (host), UART4 (+Y), UART5 (-Y),
            // USART6 (+Z), UART7 (-Z); the firmware's fixed map is in port order.
            EmulatedBoard::Netduinoplus2 => {
                let [px, nx, py, ny, pz, nz] = uart_ports::<6>(coord, array)?.map(as_serial);
                Ok(vec![px, nx, Serial::Host, py, ny, pz, nz])
            }
        }
    }

    /// Where the firmware looks for the id the host gives the board: the
    /// last 16 bytes of the RAM its memory map claims (see the firmware's
    /// `board/identity.rs`).
    const fn id_cell(self) -> u32 {
        match self {
            EmulatedBoard::Mps2An385 => 0x2000_FFF0,
            EmulatedBoard::Netduinoplus2 => 0x2002_FFF0,
        }
    }

    /// QEMU's log options that record writes to the board's user LEDs: the
    /// mps2's FPGA register trace; the STM32 model's GPIO is an unimplemented
    /// device, whose writes QEMU logs as such.
    fn light_log_args(self) -> &'static [&'static str] {
        match self {
            EmulatedBoard::Mps2An385 => &["-trace", "mps2_fpgaio_write"],
            EmulatedBoard::Netduinoplus2 => &["-d", "unimp"],
        }
    }

    fn machine_args(self) -> &'static [&'static str] {
        match self {
            EmulatedBoard::Mps2An385 => &["-machine", "mps2-an385", "-cpu", "cortex-m3"],
            EmulatedBoard::Netduinoplus2 => &["-machine", "netduinoplus2"],
        }
    }
}

/// Marks the id written into an emulated board's id cell (the firmware's
/// `identity::EMULATED_MARK`).
const ID_MARK: u64 = 0x1D5E_7B0A;

/// Two cable ends plugged into each other's sockets: a mistake made on
/// purpose, to test the cabling check. `(node, port)` names an end.
pub type Crossing = ((usize, Port), (usize, Port));

/// How to launch an array; the default is correctly cabled and logs nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Launch<'a> {
    /// Pairs of cable ends plugged into each other's sockets.
    pub crossed: &'a [Crossing],
    /// Log every write to the boards' user LEDs ([`QemuArray::log`]).
    pub log_lights: bool,
    /// Faults the relay deals to the frames between the boards.
    pub faults: Option<Faults>,
}

/// Running QEMU instances, the ptys of their host UARTs and the relay
/// joining their neighbour UARTs.
pub struct QemuArray {
    children: Vec<Child>,
    /// What each emulator printed besides its pty (the firmware's panic or
    /// fault report comes through semihosting).
    said: Vec<Arc<Mutex<Vec<String>>>>,
    /// The threads reading each emulator's output, until it ends.
    readers: Vec<Vec<std::thread::JoinHandle<()>>>,
    /// Host-side device of each node, in node order.
    pub ptys: Vec<String>,
    /// The id each node's board was given, in node order.
    pub ids: Vec<BoardId>,
    relay: Relay,
    sockets: tempfile::TempDir,
}

impl QemuArray {
    /// Starts one `board` instance per node of `array` running `firmware`.
    pub fn launch(board: EmulatedBoard, array: [u16; 3], firmware: &Path) -> Result<Self, HostError> {
        Self::launch_with(board, array, firmware, Launch::default())
    }

    /// [`Self::launch`], cabled and logged as `how` says.
    pub fn launch_with(
        board: EmulatedBoard,
        array: [u16; 3],
        firmware: &Path,
        how: Launch<'_>,
    ) -> Result<Self, HostError> {
        let crossed = how.crossed;
        if !firmware.is_file() {
            return Err(HostError::Io(format!(
                "firmware {} not found; build it with scripts/firmware.sh or give --firmware",
                firmware.display()
            )));
        }
        let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
        let salt = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos())
            ^ std::process::id().rotate_left(13);
        let mut plans = Vec::with_capacity(nodes);
        for id in 0..nodes {
            let coord = coord_of(id, array);
            let serials = board.serials(coord, array).map_err(|port| {
                input(format!(
                    "node {id} ({},{},{}) needs a link on {port:?}, but an {} has {} neighbour UARTs; \
                     use --board netduinoplus2 (six) or an array with at most {} neighbours per node",
                    coord[0],
                    coord[1],
                    coord[2],
                    board.name(),
                    board.neighbour_uarts(),
                    board.neighbour_uarts()
                ))
            })?;
            plans.push(serials);
        }
        let sockets = tempfile::Builder::new()
            .prefix("sliding-qemu")
            .tempdir()
            .map_err(|e| HostError::Io(format!("socket directory: {e}")))?;
        let mut qemu = QemuArray {
            children: Vec::new(),
            said: (0..nodes).map(|_| Arc::new(Mutex::new(Vec::new()))).collect(),
            readers: Vec::new(),
            ptys: vec![String::new(); nodes],
            ids: (0..nodes).map(|i| fresh_id(i, salt)).collect(),
            relay: Relay::with_faults(how.faults),
            sockets,
        };
        let cable = |end: (usize, Port)| {
            let other =
                crossed.iter().find_map(|&(a, b)| (a == end).then_some(b).or((b == end).then_some(a)));
            let (node, port) = other.unwrap_or(end);
            link_of(node, port, array)
        };
        let (tx, rx) = mpsc::channel();
        for (id, serials) in plans.iter().enumerate() {
            let mut cmd = Command::new("nice");
            cmd.args(["-n", "10", QEMU]);
            cmd.args(board.machine_args());
            cmd.args(["-display", "none", "-monitor", "none", "-icount", "shift=0"]);
            cmd.args(["-semihosting-config", "enable=on,target=native"]);
            let mut host_label = String::new();
            for (i, serial) in serials.iter().enumerate() {
                match serial {
                    Serial::Host => {
                        host_label = format!("serial{i}");
                        cmd.args(["-serial", "pty"]);
                    }
                    Serial::Unused => {
                        cmd.args(["-serial", "null"]);
                    }
                    Serial::Neighbour(port) => {
                        let path = qemu.sockets.path().join(format!("n{id}-{}.sock", port.index()));
                        let listener = UnixListener::bind(&path)
                            .map_err(|e| HostError::Io(format!("link socket {}: {e}", path.display())))?;
                        qemu.relay.end(cable((id, *port)), id, *port, listener);
                        cmd.args(["-chardev", &format!("socket,id=n{i},path={}", path.display())]);
                        cmd.args(["-serial", &format!("chardev:n{i}")]);
                    }
                }
            }
            let cell = board.id_cell();
            let value = (ID_MARK << 32) | u64::from(qemu.ids[id].0[0]);
            cmd.args(["-device", &format!("loader,addr={cell:#x},data={value:#x},data-len=8")]);
            if how.log_lights {
                cmd.args(board.light_log_args()).arg("-D").arg(qemu.log_path(id));
            }
            cmd.arg("-kernel").arg(firmware);
            cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
            let mut child = cmd.spawn().map_err(|e| {
                HostError::Io(format!(
                    "cannot start {QEMU}: {e}; install it (Debian: apt-get install qemu-system-arm)"
                ))
            })?;
            let readers = watch_for_pty(id, host_label, &mut child, tx.clone(), qemu.said[id].clone());
            qemu.readers.push(readers);
            qemu.children.push(child);
        }
        for _ in 0..nodes {
            match rx.recv_timeout(START_TIMEOUT) {
                Ok((id, Ok(pty))) => qemu.ptys[id] = pty,
                Ok((id, Err(why))) => return Err(HostError::Node(format!("QEMU of node {id} {why}"))),
                Err(_) => return Err(HostError::Node("QEMU did not report its pty within 20 s".into())),
            }
        }
        qemu.relay.join(START_TIMEOUT)?;
        Ok(qemu)
    }

    /// Where node `node`'s emulator logs ([`Launch::log_lights`]).
    fn log_path(&self, node: usize) -> PathBuf {
        self.sockets.path().join(format!("n{node}.log"))
    }

    /// Node `node`'s emulator log so far (empty unless launched with
    /// [`Launch::log_lights`]).
    pub fn log(&self, node: usize) -> String {
        std::fs::read_to_string(self.log_path(node)).unwrap_or_default()
    }

    /// What the emulators printed besides their ptys, each line naming its
    /// node: a panicking or faulting firmware's last words.
    pub fn last_words(&mut self) -> Vec<String> {
        // An emulator whose firmware failed ends at once, but its report may
        // still be in the pipe when the host sees its link close: wait a
        // little for the emulators to end, and read all that ended have said.
        let deadline = std::time::Instant::now() + Duration::from_millis(500);
        for (child, readers) in self.children.iter_mut().zip(&mut self.readers) {
            loop {
                match child.try_wait() {
                    Ok(Some(_)) => {
                        for reader in readers.drain(..) {
                            let _ = reader.join();
                        }
                        break;
                    }
                    Ok(None) if std::time::Instant::now() < deadline => {
                        std::thread::sleep(Duration::from_millis(10));
                    }
                    _ => break,
                }
            }
        }
        let lines = |(i, said): (usize, &Arc<Mutex<Vec<String>>>)| {
            let said = said.lock().map(|s| s.clone()).unwrap_or_default();
            said.into_iter().map(move |line| format!("node {i}: {line}"))
        };
        self.said.iter().enumerate().flat_map(lines).collect()
    }

    /// Process id of node `node`'s emulator (to stop or freeze it in tests).
    pub fn pid(&self, node: usize) -> Option<u32> {
        self.children.get(node).map(Child::id)
    }

    /// Bytes the relay carried from node `node`, per neighbour port (port
    /// order, host first and always zero).
    pub fn bytes_relayed(&self, node: usize) -> [u64; 7] {
        self.relay.bytes_from(node)
    }
}

/// A board id for node `i`: the launch's salt above, the node's number plus
/// one below, so the ids differ from node to node and from launch to launch
/// and are never zero.
fn fresh_id(i: usize, salt: u32) -> BoardId {
    let high = salt.wrapping_mul(0x9E37_79B9) & 0xFFFF_0000;
    BoardId([high | ((i as u32 + 1) & 0xFFFF), 0, 0])
}

/// The link from node `id` through `port`: (lower node, its port, higher
/// node), the same from either end.
fn link_of(id: usize, port: Port, array: [u16; 3]) -> (usize, Port, usize) {
    let axis = port.axis().unwrap_or(0);
    let mut other = coord_of(id, array);
    if let Some(c) = other.get_mut(axis) {
        *c = if port.index().is_multiple_of(2) { *c + 1 } else { *c - 1 };
    }
    let other = usize::from(index_of(other, array).unwrap_or(0));
    if id < other { (id, port, other) } else { (other, port.opposite(), id) }
}

impl Drop for QemuArray {
    fn drop(&mut self) {
        for child in &mut self.children {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Reads QEMU's "char device redirected to /dev/pts/N (label serialK)" line
/// for the host UART's label; keeps every other line in `said`.
fn watch_for_pty(
    id: usize,
    label: String,
    child: &mut Child,
    tx: mpsc::Sender<(usize, Result<String, String>)>,
    said: Arc<Mutex<Vec<String>>>,
) -> Vec<std::thread::JoinHandle<()>> {
    let streams: Vec<Box<dyn std::io::Read + Send>> = [
        child.stderr.take().map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
        child.stdout.take().map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
    ]
    .into_iter()
    .flatten()
    .collect();
    let mut readers = Vec::new();
    for stream in streams {
        let tx = tx.clone();
        let said = said.clone();
        let label = format!("(label {label})");
        readers.push(std::thread::spawn(move || {
            let mut mine = Vec::new();
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                if let Some(rest) = line.split("redirected to ").nth(1)
                    && line.contains(&label)
                {
                    let pty = rest.split_whitespace().next().unwrap_or_default().to_string();
                    let _ = tx.send((id, Ok(pty)));
                } else {
                    if let Ok(mut said) = said.lock() {
                        said.push(line.clone());
                    }
                    mine.push(line);
                }
            }
            if !mine.is_empty() {
                let _ = tx.send((id, Err(format!("exited: {}", mine.join(" / ")))));
            }
        }));
    }
    readers
}

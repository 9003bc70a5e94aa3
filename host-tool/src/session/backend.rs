//! Where a render runs: the in-memory board, emulated boards, or real boards.

use std::path::PathBuf;
use std::time::Duration;

use crate::error::{HostError, input};
use crate::plan::options::RenderOptions;
use crate::plan::{Plan, initial_partition};
use crate::results::RenderResult;
use crate::scene::Scene;
use crate::session::clock::{Cycles, HostMicros};
use crate::session::qemu::{EmulatedBoard, Launch, QemuArray};
use crate::session::sequence::{self, FrameSink, Sequence};
use crate::session::serial::SerialArray;
use crate::session::sim::render_sim;
use crate::session::transport::Transport;

/// What carries the frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Backend {
    /// The in-memory board (deterministic virtual time).
    Sim,
    /// One emulated board per node running this firmware ELF.
    Qemu {
        /// The board QEMU emulates.
        board: EmulatedBoard,
        /// The node firmware built for it.
        firmware: PathBuf,
    },
    /// Real boards, node `i` on serial device `i`.
    Serial {
        /// Serial devices in node order, or in any order with `order_ports`.
        ports: Vec<String>,
        /// Put the devices in array order by their cabling.
        order_ports: bool,
    },
}

impl Backend {
    /// The name summaries give it: `sim`, `qemu (<board>)` or `serial`.
    pub fn name(&self) -> String {
        match self {
            Self::Sim => "sim".to_string(),
            Self::Qemu { board, .. } => format!("qemu ({})", board.name()),
            Self::Serial { .. } => "serial".to_string(),
        }
    }
}

/// A frame rendered on some backend, its times on that backend's clock.
#[derive(Debug, Clone)]
pub enum Rendered {
    /// On the in-memory board, in virtual cycles.
    Sim(RenderResult<Cycles>),
    /// On boards, emulated or real, timed by the host's clock.
    Boards(RenderResult<HostMicros>),
}

/// Renders `scene` on `backend`; a node silent for `node_timeout` ends the
/// run with an error naming it.
pub fn render(
    scene: &Scene,
    opts: &RenderOptions,
    backend: &Backend,
    node_timeout: Duration,
) -> Result<Rendered, HostError> {
    match backend {
        Backend::Sim => render_sim(scene, opts).map(Rendered::Sim),
        Backend::Qemu { board, firmware } => {
            render_qemu(scene, opts, *board, firmware, node_timeout).map(Rendered::Boards)
        }
        Backend::Serial { ports, order_ports } => {
            check_port_count(opts, ports)?;
            render_serial(scene, opts, ports, *order_ports, node_timeout).map(Rendered::Boards)
        }
    }
}

/// Renders `scene` on an array of emulated `board`s running `firmware`.
fn render_qemu(
    scene: &Scene,
    opts: &RenderOptions,
    board: EmulatedBoard,
    firmware: &std::path::Path,
    node_timeout: Duration,
) -> Result<RenderResult<HostMicros>, HostError> {
    on_qemu(scene, opts, board, firmware, |ptys| {
        render_on(scene, opts, ptys, false, node_timeout, Devices::Emulators)
    })
}

/// What answers on the serial devices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Devices {
    /// Boards, which take the host's bytes as they come.
    Boards,
    /// QEMU's emulated boards, which take them only while idle
    /// ([`SerialArray::map_first`]).
    Emulators,
}

/// Runs `job` on the ptys of an array of emulated `board`s running
/// `firmware`, and stops the emulators.
fn on_qemu<R>(
    scene: &Scene,
    opts: &RenderOptions,
    board: EmulatedBoard,
    firmware: &std::path::Path,
    job: impl FnOnce(&[String]) -> Result<R, HostError>,
) -> Result<R, HostError> {
    // Check the scene before starting the emulators.
    initial_partition(scene, opts, sim_board::SimNode::capacity())?;
    let how = Launch { faults: opts.sim.faults, ..Launch::default() };
    let mut qemu = QemuArray::launch_with(board, opts.array, firmware, how)?;
    let result = job(&qemu.ptys);
    let last_words = qemu.last_words();
    drop(qemu);
    // A firmware that panicked or faulted said where, on its emulator's output.
    result.map_err(|e| match last_words.as_slice() {
        [] => e,
        words => e.append(&format!("; the emulators said: {}", words.join(" / "))),
    })
}

/// Renders `scene` on boards behind serial devices `ports`: in node order,
/// or put in it by their cabling with `order_ports`. The cabling is checked
/// before anything is sent.
pub fn render_serial(
    scene: &Scene,
    opts: &RenderOptions,
    ports: &[String],
    order_ports: bool,
    node_timeout: Duration,
) -> Result<RenderResult<HostMicros>, HostError> {
    render_on(scene, opts, ports, order_ports, node_timeout, Devices::Boards)
}

/// [`render_serial`] on `devices`.
fn render_on(
    scene: &Scene,
    opts: &RenderOptions,
    ports: &[String],
    order_ports: bool,
    node_timeout: Duration,
    devices: Devices,
) -> Result<RenderResult<HostMicros>, HostError> {
    let mut array = open_serial(opts, ports, order_ports, node_timeout, devices)?;
    // Fitted to what the boards can hold, known once they have said hello.
    let plan = Plan::new(scene, opts, array.capacity())?;
    crate::session::run(&mut array, scene, &plan)
}

/// Opens the boards behind `ports`, hears their hellos and checks their
/// cabling against `opts.array`.
fn open_serial(
    opts: &RenderOptions,
    ports: &[String],
    order_ports: bool,
    node_timeout: Duration,
    devices: Devices,
) -> Result<SerialArray, HostError> {
    let names = (0..opts.array.iter().map(|&n| usize::from(n)).product())
        .map(|i| {
            let c = node_fw::wiring::coord_of(i, opts.array);
            format!("node {i} ({},{},{})", c[0], c[1], c[2])
        })
        .collect();
    // On boards the faults hit the host links (and, emulated, the relay).
    let mut array = SerialArray::open(ports, names, node_timeout)?.with_faults(opts.sim.faults);
    if devices == Devices::Emulators {
        array = array.map_first();
    }
    array.connect()?;
    if order_ports {
        let ordered = array.order_by_cabling(opts.array)?;
        eprintln!("devices in array order: --ports {}", ordered.join(","));
    }
    array.check_cabling(opts.array)?;
    Ok(array)
}

/// Renders `sequence` of `scene` on `backend`, each frame to `sink` as it is done.
pub fn render_sequence(
    scene: &Scene,
    opts: &RenderOptions,
    backend: &Backend,
    node_timeout: Duration,
    sequence: &Sequence,
    sink: &mut impl FrameSink,
) -> Result<(), HostError> {
    let mut on_boards = |ports: &[String], order_ports: bool, devices: Devices| {
        let mut array = open_serial(opts, ports, order_ports, node_timeout, devices)?;
        sequence::run(&mut array, scene, opts, sequence, |f| sink.take(f))
    };
    match backend {
        Backend::Sim => sequence::run(&mut super::sim::board(opts), scene, opts, sequence, |f| sink.take(f)),
        Backend::Qemu { board, firmware } => {
            on_qemu(scene, opts, *board, firmware, |ptys| on_boards(ptys, false, Devices::Emulators))
        }
        Backend::Serial { ports, order_ports } => {
            check_port_count(opts, ports)?;
            on_boards(ports, *order_ports, Devices::Boards)
        }
    }
}

/// Refuses a list of serial devices that is not one per node.
fn check_port_count(opts: &RenderOptions, ports: &[String]) -> Result<(), HostError> {
    let nodes: usize = opts.array.iter().map(|&n| usize::from(n)).product();
    if ports.len() == nodes {
        return Ok(());
    }
    Err(input(format!(
        "--ports lists {} devices; the {}x{}x{} array has {nodes} nodes",
        ports.len(),
        opts.array[0],
        opts.array[1],
        opts.array[2]
    )))
}

//! Where a render runs: the in-memory board, emulated boards, or real boards.

use std::path::PathBuf;
use std::time::Duration;

use crate::error::{HostError, input};
use crate::qemu::{EmulatedBoard, QemuArray};
use crate::render::{
    Array, RenderOptions, RenderResult, check_frame, initial_partition, render_on, render_sim,
};
use crate::scene::Scene;
use crate::serial::SerialArray;

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
        /// Serial devices in node order.
        ports: Vec<String>,
    },
}

/// Renders `scene` on `backend`; a node silent for `node_timeout` ends the
/// run with an error naming it.
pub fn render(
    scene: &Scene,
    opts: &RenderOptions,
    backend: &Backend,
    node_timeout: Duration,
) -> Result<RenderResult, HostError> {
    let nodes: usize = opts.array.iter().map(|&n| usize::from(n)).product();
    match backend {
        Backend::Sim => render_sim(scene, opts),
        Backend::Qemu { board, firmware } => {
            // Check the scene before starting eight emulators.
            initial_partition(scene, opts, sim_board::SimNode::capacity())?;
            let qemu = QemuArray::launch(*board, opts.array, firmware)?;
            let result = render_serial(scene, opts, &qemu.ptys, node_timeout);
            drop(qemu);
            result
        }
        Backend::Serial { ports } if ports.len() != nodes => Err(input(format!(
            "--ports lists {} devices; the {}x{}x{} array has {nodes} nodes",
            ports.len(),
            opts.array[0],
            opts.array[1],
            opts.array[2]
        ))),
        Backend::Serial { ports } => render_serial(scene, opts, ports, node_timeout),
    }
}

/// Renders `scene` on boards behind serial devices `ports` (node order).
pub fn render_serial(
    scene: &Scene,
    opts: &RenderOptions,
    ports: &[String],
    node_timeout: Duration,
) -> Result<RenderResult, HostError> {
    let names = (0..opts.array.iter().map(|&n| usize::from(n)).product())
        .map(|i| {
            let c = node_fw::wiring::coord_of(i, opts.array);
            format!("node {i} ({},{},{})", c[0], c[1], c[2])
        })
        .collect();
    let mut array = SerialArray::open(ports, names, node_timeout)?;
    array.connect()?;
    // Fitted to what the boards can hold, known once they have said hello.
    let partition = initial_partition(scene, opts, array.capacity())?;
    check_frame(scene, opts, &partition, array.capacity())?;
    render_on(&mut array, scene, opts, partition)
}

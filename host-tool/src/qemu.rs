//! An array of emulated boards: one QEMU mps2-an385 per node, wired UART to
//! UART through Unix sockets, each joined to the host over a pty.
//!
//! Node `i` runs the node firmware; its UART 0 is a pty the host opens as a
//! serial device, and UARTs 1-4 go to the neighbour ports that exist, in
//! port order ([`node_fw::wiring::uart_ports`], the rule the firmware uses).
//! Of each neighbouring pair the lower node listens on the socket and the
//! higher connects (and reconnects until the listener is up). Every instance
//! runs with `-icount shift=0`, so its clock counts instructions. The
//! instances are stopped when the array is dropped.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use node_fw::Port;
use node_fw::wiring::{coord_of, index_of, uart_ports};

use crate::error::{HostError, input};

/// The QEMU binary.
pub const QEMU: &str = "qemu-system-arm";
/// Neighbour UARTs of an mps2-an385.
const NEIGHBOUR_UARTS: usize = 4;

/// Running QEMU instances and the ptys of their host UARTs.
pub struct QemuArray {
    children: Vec<Child>,
    /// Host-side device of each node, in node order.
    pub ptys: Vec<String>,
    _sockets: tempfile::TempDir,
}

impl QemuArray {
    /// Starts one instance per node of `array` running `firmware`.
    pub fn launch(array: [u16; 3], firmware: &Path) -> Result<Self, HostError> {
        if !firmware.is_file() {
            return Err(HostError::Io(format!(
                "firmware {} not found; build it with scripts/firmware.sh",
                firmware.display()
            )));
        }
        let sockets = tempfile::Builder::new()
            .prefix("sliding-qemu")
            .tempdir()
            .map_err(|e| HostError::Io(format!("socket directory: {e}")))?;
        let mut qemu = QemuArray { children: Vec::new(), ptys: Vec::new(), _sockets: sockets };
        let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
        let (tx, rx) = mpsc::channel();
        for id in 0..nodes {
            let coord = coord_of(id, array);
            let map = uart_ports::<NEIGHBOUR_UARTS>(coord, array).map_err(|port| {
                input(format!(
                    "node {id} ({},{},{}) needs a link on {port:?}, but an mps2-an385 has {NEIGHBOUR_UARTS} \
                     neighbour UARTs; use an array with at most {NEIGHBOUR_UARTS} neighbours per node",
                    coord[0], coord[1], coord[2]
                ))
            })?;
            let mut cmd = Command::new(QEMU);
            cmd.args(["-machine", "mps2-an385", "-cpu", "cortex-m3", "-display", "none", "-monitor", "none"]);
            cmd.args(["-icount", "shift=0", "-semihosting-config", "enable=on,target=native"]);
            cmd.args(["-serial", "pty"]);
            for (uart, port) in map.iter().enumerate() {
                match port {
                    Some(port) => {
                        let (socket, listen) = qemu.socket(id, coord, array, *port);
                        let role = if listen { "server=on,wait=off" } else { "reconnect=1" };
                        cmd.args([
                            "-chardev",
                            &format!("socket,id=n{uart},path={},{role}", socket.display()),
                        ]);
                        cmd.args(["-serial", &format!("chardev:n{uart}")]);
                    }
                    None => {
                        cmd.args(["-serial", "null"]);
                    }
                }
            }
            cmd.arg("-kernel").arg(firmware);
            cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
            let mut child = cmd.spawn().map_err(|e| {
                HostError::Io(format!(
                    "cannot start {QEMU}: {e}; install it (Debian: apt-get install qemu-system-arm)"
                ))
            })?;
            watch_for_pty(id, &mut child, tx.clone());
            qemu.children.push(child);
        }
        qemu.ptys = vec![String::new(); nodes];
        for _ in 0..nodes {
            match rx.recv_timeout(Duration::from_secs(20)) {
                Ok((id, Ok(pty))) => qemu.ptys[id] = pty,
                Ok((id, Err(why))) => return Err(HostError::Node(format!("QEMU of node {id} {why}"))),
                Err(_) => return Err(HostError::Node("QEMU did not report its pty within 20 s".into())),
            }
        }
        Ok(qemu)
    }

    /// Process id of node `node`'s emulator (to stop or freeze it in tests).
    pub fn pid(&self, node: usize) -> Option<u32> {
        self.children.get(node).map(Child::id)
    }

    /// The socket of the link from node `id` through `port`, and whether `id` listens on it.
    fn socket(&self, id: usize, coord: [u16; 3], array: [u16; 3], port: Port) -> (PathBuf, bool) {
        let axis = port.axis().unwrap_or(0);
        let mut other = coord;
        if let Some(c) = other.get_mut(axis) {
            *c = if port.index().is_multiple_of(2) { *c + 1 } else { *c - 1 };
        }
        let other = usize::from(index_of(other, array).unwrap_or(0));
        let (lo, hi) = (id.min(other), id.max(other));
        (self._sockets.path().join(format!("link-{lo}-{hi}.sock")), id == lo)
    }
}

impl Drop for QemuArray {
    fn drop(&mut self) {
        for child in &mut self.children {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Reads QEMU's "char device redirected to /dev/pts/N (label serial0)" line.
fn watch_for_pty(id: usize, child: &mut Child, tx: mpsc::Sender<(usize, Result<String, String>)>) {
    let streams: Vec<Box<dyn std::io::Read + Send>> = [
        child.stderr.take().map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
        child.stdout.take().map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
    ]
    .into_iter()
    .flatten()
    .collect();
    for stream in streams {
        let tx = tx.clone();
        std::thread::spawn(move || {
            let mut said = Vec::new();
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                if let Some(rest) = line.split("redirected to ").nth(1)
                    && line.contains("serial0")
                {
                    let pty = rest.split_whitespace().next().unwrap_or_default().to_string();
                    let _ = tx.send((id, Ok(pty)));
                } else {
                    said.push(line);
                }
            }
            if !said.is_empty() {
                let _ = tx.send((id, Err(format!("exited: {}", said.join(" / ")))));
            }
        });
    }
}

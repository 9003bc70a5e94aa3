//! `host-tool boards`: which boards are on the given serial devices, what
//! they run, and how they are cabled, without rendering anything.

use std::fmt::Write as _;
use std::time::Duration;

use link_proto::{BoardId, ClockSource, Hello};
use node_fw::Port;

use crate::error::HostError;
use crate::session::cabling::{self, Reported, port_name};
use crate::session::serial::SerialArray;

/// How long the boards get to report their cables when no array is given.
const LISTEN: Duration = Duration::from_secs(2);

/// Says hello to the boards on `ports` and describes them: a table of the
/// boards, their cables, and, given the `array` they should form, whether
/// the cabling is right and in which order to list the devices.
pub fn list(ports: &[String], array: Option<[u16; 3]>, timeout: Duration) -> Result<String, HostError> {
    let mut boards = SerialArray::open(ports, ports.to_vec(), timeout)?;
    boards.connect()?;
    match array {
        Some(array) => boards.gather(timeout, |r| cabling::order(r, array).is_ok())?,
        None => boards.gather(LISTEN, |_| false)?,
    }
    let reported = boards.reported();
    let mut out = table(&reported, &boards.hellos());
    out.push('\n');
    out.push_str(&cables(&reported));
    if let Some(array) = array {
        out.push('\n');
        out.push_str(&verdict(&reported, array));
    }
    Ok(out)
}

/// One row per board.
fn table(reported: &[Reported], hellos: &[Option<Hello>]) -> String {
    let mut out = String::from(
        "| device | board | id | firmware | protocol | spheres | refs | cubes | rays | clock | links | host link |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (r, hello) in reported.iter().zip(hellos) {
        let Some(h) = hello else { continue };
        let b = h.board;
        let c = h.capacity;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.device,
            b.kind.name(),
            if b.id.is_known() { b.id.to_string() } else { "none".into() },
            b.firmware,
            h.version,
            c.spheres,
            c.refs,
            c.cubes,
            c.rays,
            clock(b.clock_hz, b.clock_source),
            baud(b.link_baud),
            baud(b.host_baud)
        );
    }
    out
}

fn clock(hz: u32, source: ClockSource) -> String {
    let from = match source {
        ClockSource::PllFromExternal => "PLL from external clock",
        ClockSource::PllFromInternal => "PLL from internal oscillator",
        ClockSource::Reset => "reset clock, no PLL",
        ClockSource::Virtual => "virtual",
    };
    match hz {
        0 => from.to_string(),
        hz => format!("{} MHz ({from})", f64::from(hz) / 1e6),
    }
}

fn baud(rate: u32) -> String {
    match rate {
        0 => "-".into(),
        r => format!("{r} baud"),
    }
}

/// Each board's ports and the device of the board found there.
fn cables(reported: &[Reported]) -> String {
    let device_of = |id: BoardId| reported.iter().find(|r| r.board.id == id).map(|r| r.device.clone());
    let mut out = String::from("cables (port: the device of the board there):\n");
    for r in reported {
        let ends: Vec<String> = Port::NEIGHBOURS
            .iter()
            .filter_map(|&p| {
                let id = r.peers[p.index()]?;
                Some(format!("{} {}", port_name(p), device_of(id).unwrap_or_else(|| format!("board {id}"))))
            })
            .collect();
        let ends = if ends.is_empty() { "none seen".to_string() } else { ends.join(", ") };
        let _ = writeln!(out, "  {}: {ends}", r.device);
    }
    out
}

/// Whether the boards form `array`, and the order to list them in.
fn verdict(reported: &[Reported], array: [u16; 3]) -> String {
    let [x, y, z] = array;
    match cabling::order(reported, array) {
        Ok(order) => {
            let devices: Vec<&str> = order.iter().map(|&d| reported[d].device.as_str()).collect();
            format!("cabled as a {x}x{y}x{z} array; in array order: --ports {}\n", devices.join(","))
        }
        Err(why) => {
            let faults = cabling::check(reported, array);
            let listed: Vec<String> = faults.iter().map(|f| cabling::describe(f, reported, array)).collect();
            format!(
                "not cabled as a {x}x{y}x{z} array: {why}\nin the order given:\n  {}\n",
                if listed.is_empty() { "no fault".to_string() } else { listed.join("\n  ") }
            )
        }
    }
}

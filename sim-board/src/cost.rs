//! What work and links cost in virtual time (ticks: CPU cycles of a node).

use node_fw::Work;

/// Cycles charged per unit of node work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CostModel {
    /// One unit-cube step of the digital line.
    pub cube_step: u64,
    /// One ray/sphere test.
    pub sphere_test: u64,
    /// Setting up one walk (validating and resuming a ray).
    pub trace: u64,
    /// Shading one hit (evaluating and spawning children).
    pub shade: u64,
    /// Creating one initial ray (camera direction, grid entry).
    pub create: u64,
    /// Handling one received or sent message.
    pub message: u64,
}

impl Default for CostModel {
    /// Cortex-M3 instructions of the node firmware, measured on the emulated
    /// mps2-an385 (`scripts/firmware.sh` runs the `kernels` binary under
    /// `qemu-system-arm -icount shift=0`): a walked cube (step and inside
    /// test) 117.1; a sphere test over a mostly-missing list 224.0; a walk's
    /// set-up (the received ray's line checked, the walk resumed) 767.9; a
    /// shaded hit with one light and a mirror 72 353.5 (the surface and both
    /// children, evaluated once to count and once to spawn them); an initial
    /// ray (pixel line, ray, entry cube) 12 510.0; one end of a ray message
    /// through a reliable channel, acks included, 4 557.8 (the UART's bytes
    /// are the link model's).
    fn default() -> Self {
        Self { cube_step: 117, sphere_test: 224, trace: 768, shade: 72_354, create: 12_510, message: 4_558 }
    }
}

impl CostModel {
    /// Cycles for one poll's work (at least one if anything was done).
    pub fn charge(&self, w: &Work) -> u64 {
        let c = u64::from(w.cube_steps) * self.cube_step
            + u64::from(w.sphere_tests) * self.sphere_test
            + u64::from(w.traces) * self.trace
            + u64::from(w.shades) * self.shade
            + u64::from(w.created) * self.create
            + u64::from(w.received + w.sent) * self.message;
        c.max(u64::from(w.is_busy()))
    }
}

/// A link's timing: serialisation per byte, then a fixed latency.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkModel {
    /// Cycles to put one byte on the wire.
    pub byte: u64,
    /// Cycles from the last byte sent to the message's arrival.
    pub latency: u64,
    /// Messages a link holds before the sender sees it full.
    pub capacity: usize,
}

impl Default for LinkModel {
    fn default() -> Self {
        Self { byte: 25, latency: 2_000, capacity: 8 }
    }
}

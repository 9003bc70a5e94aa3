//! The board's lights show what the node is doing, so that a glance at a
//! physical array shows where the load is.
//!
//! One light is lit while the node works and dark while it waits: at the
//! loop's rate the eye sees it glow with the node's load (running over
//! running plus waiting, the paper's load). The other is lit once the node
//! has failed. Both are embedded-hal output pins, whatever drives them.

use embedded_hal::digital::{OutputPin, PinState};

/// What the node is doing, as the lights show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Activity {
    /// The last pass did work: rays, messages, set-up.
    Running,
    /// Nothing to do until a byte or a timer comes.
    Waiting,
    /// Stopped after reporting an error to the host.
    Failed,
}

/// A working light and a fault light.
#[derive(Debug)]
pub struct Lights<W, F> {
    working: W,
    fault: F,
    shown: Option<Activity>,
}

impl<W: OutputPin, F: OutputPin> Lights<W, F> {
    /// Both lights, dark.
    pub fn new(working: W, fault: F) -> Self {
        let mut lights = Self { working, fault, shown: None };
        lights.show(Activity::Waiting);
        lights
    }

    /// Shows `activity`; the pins are written only when it changes.
    pub fn show(&mut self, activity: Activity) {
        if self.shown == Some(activity) {
            return;
        }
        self.shown = Some(activity);
        // A pin that cannot be driven is no reason to stop the node.
        let _ = self.working.set_state(PinState::from(activity == Activity::Running));
        let _ = self.fault.set_state(PinState::from(activity == Activity::Failed));
    }
}

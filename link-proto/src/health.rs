//! What a node tells the host of its links: the frames it sent again, the
//! frames that reached it damaged and the bytes its receivers lost, per port.
//!
//! On a real array a bad cable, a noisy line or a receiver that cannot keep
//! up costs only time: the reliable channels resend until every frame gets
//! through, and the image stays right. Without these counts such a fault
//! shows only as a slow frame. The host sees its own ends of the host links;
//! only the node sees the links between nodes.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// One port's troubles over some span of time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
pub struct PortHealth {
    /// Data frames sent again: lost or damaged on the way, or their
    /// acknowledgement was.
    pub resent: u32,
    /// Frames that arrived damaged: a failed check or a frame that would not
    /// decode (line noise, a loose cable, bytes the receiver lost).
    pub damaged: u32,
    /// Received bytes the board lost before it read them: its UART overran
    /// (an interrupt held off too long, a loop too slow to poll) or its
    /// receive ring was full. The board's fault, not the cable's; each one
    /// also damages a frame.
    pub lost: u32,
}

impl PortHealth {
    /// Whether nothing went wrong.
    pub fn is_clean(&self) -> bool {
        *self == Self::default()
    }

    /// What happened between two readings of cumulative counts, `self` the
    /// later (counters that wrapped count from zero again).
    pub fn since(self, earlier: Self) -> Self {
        Self {
            resent: self.resent.wrapping_sub(earlier.resent),
            damaged: self.damaged.wrapping_sub(earlier.damaged),
            lost: self.lost.wrapping_sub(earlier.lost),
        }
    }
}

impl core::ops::AddAssign for PortHealth {
    fn add_assign(&mut self, o: Self) {
        self.resent = self.resent.saturating_add(o.resent);
        self.damaged = self.damaged.saturating_add(o.damaged);
        self.lost = self.lost.saturating_add(o.lost);
    }
}

/// Node to host, before its final load report of a frame, when one of its
/// links had trouble since its last such report. A node whose links were
/// clean sends none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct LinkHealth {
    /// Reporting node.
    pub node: u16,
    /// Per port, in the node's port order: +x, -x, +y, -y, +z, -z, host.
    pub ports: [PortHealth; 7],
}

#[cfg(test)]
mod tests {
    use super::PortHealth;

    #[test]
    fn since_takes_the_difference_across_a_wrap() {
        let earlier = PortHealth { resent: u32::MAX - 1, damaged: 5, lost: u32::MAX };
        let later = PortHealth { resent: 3, damaged: 5, lost: 1 };
        assert_eq!(later.since(earlier), PortHealth { resent: 5, damaged: 0, lost: 2 });
        assert!(later.since(later).is_clean());
    }

    #[test]
    fn sums_saturate() {
        let mut a = PortHealth { resent: u32::MAX, damaged: 1, lost: 4 };
        a += PortHealth { resent: 1, damaged: 2, lost: u32::MAX };
        assert_eq!(a, PortHealth { resent: u32::MAX, damaged: 3, lost: u32::MAX });
    }
}

//! Bytes waiting for a UART: whole frames in, runs of bytes out.

use heapless::Deque;

/// Bytes of one port's transmit ring (two largest frames and some).
pub const TX_RING: usize = 384;

/// A transmit ring that takes a frame whole or not at all, so a frame is
/// never cut by back-pressure.
#[derive(Debug, Default)]
pub struct TxRing {
    bytes: Deque<u8, TX_RING>,
}

impl TxRing {
    /// An empty ring.
    pub const fn new() -> Self {
        Self { bytes: Deque::new() }
    }

    /// Queues `frame` if all of it fits; returns whether it did.
    pub fn push_frame(&mut self, frame: &[u8]) -> bool {
        if self.bytes.capacity() - self.bytes.len() < frame.len() {
            return false;
        }
        for &b in frame {
            // Room was checked above.
            let _ = self.bytes.push_back(b);
        }
        true
    }

    /// The oldest waiting bytes that lie one after another in the ring
    /// (empty when none wait): a UART's writer takes such a run in one call
    /// (on the STM32 boards, one critical section for all it queues), where
    /// a call a byte paid that call's whole cost for every byte.
    #[inline]
    pub fn front_run(&self) -> &[u8] {
        self.bytes.as_slices().0
    }

    /// Drops the `n` oldest bytes, just sent.
    #[inline]
    pub fn consume(&mut self, n: usize) {
        for _ in 0..n {
            self.bytes.pop_front();
        }
    }

    /// Whether nothing waits.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

//! Bytes waiting for a UART: whole frames in, single bytes out.

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

    /// The next byte to send, if any.
    #[inline]
    pub fn front(&self) -> Option<u8> {
        self.bytes.front().copied()
    }

    /// Drops the byte just sent.
    #[inline]
    pub fn pop(&mut self) {
        self.bytes.pop_front();
    }

    /// Whether nothing waits.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

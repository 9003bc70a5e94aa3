//! Bytes between a UART's interrupt handler and the main loop.
//!
//! A UART holds one byte each way: at 3.125 Mbaud the next arrives, or may
//! leave, 3.2 us later, 320 cycles at 100 MHz, while a pass of the node's
//! loop that shades a hit takes thousands. Polled, the bytes received in
//! between are overrun (and their frame resent), and the line stands idle
//! where it could send. So the handler moves each received byte into one
//! ring and each byte to send out of another, as the UART is ready, and the
//! loop drains and fills the rings when it comes round.
//!
//! One producer and one consumer (the handler and the loop, one way or the
//! other): each index is written by one side only, and a byte is published
//! by the release store of `head` after it is written, so no lock is needed.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU16, AtomicU32, Ordering};

/// A single-producer, single-consumer ring of `N` bytes (a power of two).
pub struct ByteRing<const N: usize> {
    bytes: UnsafeCell<[u8; N]>,
    /// Bytes ever pushed, wrapping; written by the producer only.
    head: AtomicU16,
    /// Bytes ever popped, wrapping; written by the consumer only.
    tail: AtomicU16,
    /// Received bytes lost: to a full ring, or overrun in the UART before
    /// the handler ran. The reliable channel resends what they belonged to.
    lost: AtomicU32,
}

// SAFETY: the producer writes only the slot at `head` and then `head`; the
// consumer reads only slots before `head` (acquired) and writes only
// `tail`. A slot is never written while the consumer may read it, because
// the producer does not pass `tail + N`.
unsafe impl<const N: usize> Sync for ByteRing<N> {}

impl<const N: usize> ByteRing<N> {
    const FITS: () = assert!(N.is_power_of_two() && N <= 1 << 15, "the indices wrap at 2^16");

    /// An empty ring.
    pub const fn new() -> Self {
        let () = Self::FITS;
        Self {
            bytes: UnsafeCell::new([0; N]),
            head: AtomicU16::new(0),
            tail: AtomicU16::new(0),
            lost: AtomicU32::new(0),
        }
    }

    /// Producer side: appends `byte`; false, and nothing changes, when the
    /// ring is full.
    pub fn push(&self, byte: u8) -> bool {
        let head = self.head.load(Ordering::Relaxed);
        let tail = self.tail.load(Ordering::Acquire);
        if usize::from(head.wrapping_sub(tail)) >= N {
            return false;
        }
        // SAFETY: the slot is inside the array (`% N`), and the consumer
        // does not read it until `head` moves past it below (see the `Sync`
        // impl). Only this byte is written: no reference to the array is
        // made while the consumer may be reading other slots.
        unsafe { self.bytes.get().cast::<u8>().add(usize::from(head) % N).write(byte) };
        self.head.store(head.wrapping_add(1), Ordering::Release);
        true
    }

    /// Producer side: a byte was lost before it could be pushed.
    pub fn note_lost(&self) {
        // Only the producer writes `lost`: no read-modify-write is needed.
        self.lost.store(self.lost.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
    }

    /// Consumer side: the oldest byte, if any.
    pub fn pop(&self) -> Option<u8> {
        let tail = self.tail.load(Ordering::Relaxed);
        if self.head.load(Ordering::Acquire) == tail {
            return None;
        }
        // SAFETY: the slot is inside the array (`% N`); it was published by
        // the producer's release store of `head`, acquired above, and it is
        // not rewritten until `tail` moves past it below.
        let byte = unsafe { self.bytes.get().cast::<u8>().add(usize::from(tail) % N).read() };
        self.tail.store(tail.wrapping_add(1), Ordering::Release);
        Some(byte)
    }

    /// Whether no byte waits (either side may ask).
    pub fn is_empty(&self) -> bool {
        self.head.load(Ordering::Acquire) == self.tail.load(Ordering::Acquire)
    }

    /// Producer side: whether a push would fail.
    pub fn is_full(&self) -> bool {
        let head = self.head.load(Ordering::Relaxed);
        usize::from(head.wrapping_sub(self.tail.load(Ordering::Acquire))) >= N
    }

    /// Received bytes lost so far.
    pub fn lost(&self) -> u32 {
        self.lost.load(Ordering::Relaxed)
    }
}

impl<const N: usize> core::fmt::Debug for ByteRing<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ByteRing").field("empty", &self.is_empty()).field("lost", &self.lost()).finish()
    }
}

impl<const N: usize> Default for ByteRing<N> {
    fn default() -> Self {
        Self::new()
    }
}

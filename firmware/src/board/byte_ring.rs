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
//! by the store of `head` after it is written, so no lock is needed.
//!
//! Both sides run on one core, the handler interrupting the loop: a core
//! sees its own loads and stores in program order, so only the compiler
//! must be kept from reordering them, which [`compiler_fence`] does (its
//! documented use: a thread and the interrupt or signal handler that runs
//! on it). Acquire and release atomics would each add a `dmb` on a
//! Cortex-M, two to every byte the handler moves, for an order the core
//! keeps anyway.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU16, AtomicU32, Ordering, compiler_fence};

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
// consumer reads only slots before `head` (read before the slots, in
// program order) and writes only `tail`. A slot is never written while the
// consumer may read it, because the producer does not pass `tail + N`. Both
// run on one core (see the module's note), so program order is the order
// each sees the other's accesses in.
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
        let tail = self.tail.load(Ordering::Relaxed);
        // The slot is free once `tail` says so: read it before writing there.
        compiler_fence(Ordering::Acquire);
        if usize::from(head.wrapping_sub(tail)) >= N {
            return false;
        }
        // SAFETY: the slot is inside the array (`% N`), and the consumer
        // does not read it until `head` moves past it below (see the `Sync`
        // impl). Only this byte is written: no reference to the array is
        // made while the consumer may be reading other slots.
        unsafe { self.bytes.get().cast::<u8>().add(usize::from(head) % N).write(byte) };
        // The byte before the index that publishes it.
        compiler_fence(Ordering::Release);
        self.head.store(head.wrapping_add(1), Ordering::Relaxed);
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
        let head = self.head.load(Ordering::Relaxed);
        // The index that published the byte before the byte.
        compiler_fence(Ordering::Acquire);
        if head == tail {
            return None;
        }
        // SAFETY: the slot is inside the array (`% N`); it was published by
        // the producer's store of `head`, read above, and it is not
        // rewritten until `tail` moves past it below.
        let byte = unsafe { self.bytes.get().cast::<u8>().add(usize::from(tail) % N).read() };
        // The byte read before the slot is handed back.
        compiler_fence(Ordering::Release);
        self.tail.store(tail.wrapping_add(1), Ordering::Relaxed);
        Some(byte)
    }

    /// Whether no byte waits (either side may ask).
    pub fn is_empty(&self) -> bool {
        self.head.load(Ordering::Relaxed) == self.tail.load(Ordering::Relaxed)
    }

    /// Producer side: whether a push would fail.
    pub fn is_full(&self) -> bool {
        let head = self.head.load(Ordering::Relaxed);
        usize::from(head.wrapping_sub(self.tail.load(Ordering::Relaxed))) >= N
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

//! The ring arithmetic of the DMA links against a model of the streams: a
//! counter of bytes the stream wrote, NDTR as the manual defines it (the
//! bytes left in the lap, reloaded to the ring's length when a lap ends),
//! and a lap interrupt that runs late.

use clock_tree::dma::{circular_position, next_run};

/// A circular stream over a ring of `len` bytes.
struct Stream {
    len: u32,
    /// Bytes written in all (the model's truth; u64, no wrap).
    written: u64,
    /// Laps the interrupt has counted so far.
    counted: u32,
}

impl Stream {
    fn ndtr(&self) -> u16 {
        (self.len - (self.written % u64::from(self.len)) as u32) as u16
    }
    fn write(&mut self, n: u64) {
        self.written += n;
    }
    /// The interrupt runs for every lap ended.
    fn interrupt(&mut self) {
        self.counted = (self.written / u64::from(self.len)) as u32;
    }
}

#[test]
fn the_position_is_the_bytes_written_whether_or_not_the_lap_is_counted() {
    for len in [8u32, 256, 1024] {
        let mut s = Stream { len, written: 0, counted: 0 };
        // Steps of every size up to a ring, the interrupt sometimes late
        // (never more than one lap: it is late, not lost), the reader
        // anywhere less than a lap behind.
        for step in 0..(4 * u64::from(len)) {
            s.write(step % u64::from(len) + 1);
            if step % 3 != 0 || s.written / u64::from(len) > u64::from(s.counted) + 1 {
                s.interrupt();
            }
            let behind = step.wrapping_mul(7) % u64::from(len);
            let reader = s.written.saturating_sub(behind) as u32;
            let at = circular_position(s.counted, s.ndtr(), len, reader);
            assert_eq!(at, s.written as u32, "len {len}, step {step}, reader {behind} behind");
        }
    }
}

#[test]
fn positions_wrap_with_the_laps() {
    let len = 1024u32;
    let laps = u32::MAX / len; // the last lap before 2^32 wraps
    let at = circular_position(laps, 24, len, laps.wrapping_mul(len));
    assert_eq!(at, laps.wrapping_mul(len) + 1000);
    // The lap after it: NDTR reloaded, not counted yet, the reader where
    // the stream was.
    let next = circular_position(laps, len as u16, len, at);
    assert_eq!(next, laps.wrapping_mul(len).wrapping_add(len));
    assert_eq!(next, 0);
}

#[test]
fn an_ndtr_past_the_ring_reads_as_a_full_lap_left() {
    assert_eq!(circular_position(3, 5000, 1024, 3 * 1024), 3 * 1024);
}

#[test]
fn runs_cover_the_waiting_bytes_in_order_and_never_wrap() {
    let len = 256u32;
    for (sent, queued) in [(0u32, 0u32), (0, 10), (250, 260), (255, 256), (100, 356), (u32::MAX - 3, 20)] {
        // Runs taken one after another send every byte once, in order.
        let (mut at, mut order) = (sent, Vec::new());
        while let Some((start, run)) = next_run(at, queued, len) {
            assert!(run > 0 && start + run <= len, "{sent} {queued}: {start} + {run}");
            assert_eq!(start, at % len);
            order.extend((0..run).map(|i| at.wrapping_add(i)));
            at = at.wrapping_add(run);
        }
        let want: Vec<u32> = (0..queued.wrapping_sub(sent)).map(|i| sent.wrapping_add(i)).collect();
        assert_eq!(order, want, "{sent} {queued}");
    }
}

//! The fault injector beside the board's links (after smoltcp's): per frame,
//! from a seeded generator per link end, a byte corrupted, the frame dropped,
//! duplicated or delayed.

/// Fault probabilities, each per frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Faults {
    /// One byte of the frame is corrupted (a random bit flipped).
    pub corrupt: f64,
    /// The frame is lost.
    pub drop: f64,
    /// The frame arrives twice.
    pub dup: f64,
    /// The frame takes four link latencies longer.
    pub delay: f64,
    /// Seed of the generators.
    pub seed: u64,
}

/// What the wire does to one frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fate {
    /// The bytes as they arrive (possibly corrupted); empty if dropped.
    pub bytes: Vec<u8>,
    /// Copies that arrive.
    pub copies: u8,
    /// Extra latencies of delay.
    pub delayed: bool,
}

/// A seeded generator for one link end (xorshift64*).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultRng(u64);

impl FaultRng {
    /// The generator of link end `(node, port)` under `seed`.
    pub fn new(seed: u64, node: usize, port: usize) -> Self {
        let mix = seed
            ^ (node as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (port as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        Self(mix | 1)
    }

    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && ((self.next() >> 11) as f64 / (1u64 << 53) as f64) < p
    }

    /// Decides what happens to `frame`.
    pub fn fate(&mut self, faults: &Faults, frame: &[u8]) -> Fate {
        if self.chance(faults.drop) {
            return Fate { bytes: Vec::new(), copies: 0, delayed: false };
        }
        let mut bytes = frame.to_vec();
        if self.chance(faults.corrupt) && !bytes.is_empty() {
            let i = (self.next() % bytes.len() as u64) as usize;
            bytes[i] ^= 1 << (self.next() % 8);
        }
        let copies = if self.chance(faults.dup) { 2 } else { 1 };
        Fate { bytes, copies, delayed: self.chance(faults.delay) }
    }
}

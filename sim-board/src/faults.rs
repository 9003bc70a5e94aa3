//! The fault injector beside the links (after smoltcp's): per frame, from a
//! seeded generator per link end, a byte corrupted, the frame dropped,
//! duplicated or delayed. The in-memory board applies it to the frames on
//! its wires; [`FaultyStream`] applies it to any byte stream of frames (the
//! emulated boards' relay, a serial port), so `--faults` reaches every
//! transport.

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

/// SplitMix64's output function: a bijection that spreads every input bit.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A seeded generator for one link end (xorshift64*).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultRng(u64);

impl FaultRng {
    /// The generator of link end `(node, port)` under `seed`.
    ///
    /// The three are mixed by SplitMix64's finaliser, a bijection of `u64`, so
    /// distinct seeds give distinct streams on every link end. Xorshift needs a
    /// state other than zero; the one input that maps there takes a fixed
    /// non-zero state instead (forcing the low bit, as before, made seeds
    /// `2k` and `2k + 1` the same).
    pub fn new(seed: u64, node: usize, port: usize) -> Self {
        let mix = seed
            ^ (node as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (port as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        match splitmix64(mix) {
            0 => Self(0x9E37_79B9_7F4A_7C15),
            state => Self(state),
        }
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

/// The faults on a byte stream of frames, whatever carries it. Bytes are cut
/// into frames at each zero (the frame delimiter, [`link_proto::frame`]) and
/// each frame meets its [`FaultRng::fate`]; a delayed frame goes out after
/// the next one. Bytes of a frame not yet ended wait for its end.
#[derive(Debug, Clone)]
pub struct FaultyStream {
    faults: Faults,
    rng: FaultRng,
    partial: Vec<u8>,
    held: Option<Vec<u8>>,
}

impl FaultyStream {
    /// The stream leaving link end `(node, port)`.
    pub fn new(faults: Faults, node: usize, port: usize) -> Self {
        Self { faults, rng: FaultRng::new(faults.seed, node, port), partial: Vec::new(), held: None }
    }

    /// Passes `bytes` on into `out`, with the faults.
    pub fn pass(&mut self, bytes: &[u8], out: &mut impl Extend<u8>) {
        for &b in bytes {
            self.partial.push(b);
            if b != 0 {
                continue;
            }
            let segment = std::mem::take(&mut self.partial);
            // A lone delimiter is the gap between two frames.
            if segment.len() == 1 {
                out.extend(segment);
                continue;
            }
            let fate = self.rng.fate(&self.faults, &segment);
            for _ in 0..fate.copies {
                if fate.delayed && self.held.is_none() {
                    self.held = Some(fate.bytes.clone());
                } else {
                    out.extend(fate.bytes.iter().copied());
                }
            }
            if !fate.delayed
                && let Some(late) = self.held.take()
            {
                out.extend(late);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fates of 256 frames on one link end under `seed`, as drop and corrupt flags.
    fn pattern(seed: u64) -> Vec<(bool, bool)> {
        let faults = Faults { corrupt: 0.3, drop: 0.3, dup: 0.0, delay: 0.0, seed };
        let mut rng = FaultRng::new(seed, 5, 2);
        (0..256)
            .map(|_| {
                let fate = rng.fate(&faults, &[0xA5; 8]);
                (fate.copies == 0, fate.copies > 0 && fate.bytes != [0xA5; 8])
            })
            .collect()
    }

    #[test]
    fn a_stream_without_faults_passes_every_byte_and_one_with_them_loses_whole_frames() {
        let frames: Vec<u8> = (1..=200u8).flat_map(|i| [0, i, i, i, 0]).collect();
        let mut out = Vec::new();
        FaultyStream::new(Faults::default(), 0, 0).pass(&frames, &mut out);
        assert_eq!(out, frames);
        let faults = Faults { drop: 0.3, seed: 3, ..Faults::default() };
        let mut out = Vec::new();
        let mut stream = FaultyStream::new(faults, 0, 0);
        // In pieces, as a socket delivers them.
        for piece in frames.chunks(7) {
            stream.pass(piece, &mut out);
        }
        let kept: Vec<u8> = out.split(|&b| b == 0).filter(|f| !f.is_empty()).map(|f| f[0]).collect();
        assert!(kept.len() > 100 && kept.len() < 180, "{} of 200 frames kept", kept.len());
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "whole frames, in order");
        assert!(out.split(|&b| b == 0).all(|f| f.is_empty() || f.len() == 3), "no frame cut short");
    }

    #[test]
    fn neighbouring_seeds_give_different_fault_patterns() {
        // Seeds 2k and 2k + 1 once collided: the low bit was forced on.
        let patterns: Vec<_> = (0..64).map(pattern).collect();
        for (i, a) in patterns.iter().enumerate() {
            for (j, b) in patterns.iter().enumerate().skip(i + 1) {
                assert_ne!(a, b, "seeds {i} and {j} give the same faults");
            }
        }
    }

    #[test]
    fn every_link_end_has_its_own_stream() {
        let first = |node, port| FaultRng::new(7, node, port).next();
        let mut seen: Vec<u64> = (0..64).flat_map(|n| (0..7).map(move |p| first(n, p))).collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), 64 * 7);
    }
}

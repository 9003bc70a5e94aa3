//! The reliable channel over a wire that corrupts, drops and duplicates bytes:
//! every message arrives once, in order.

use link_proto::{Message, Retire};
use node_fw::reliable::Channel;

/// xorshift64*: a seeded generator, no dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn chance(&mut self, p: f64) -> bool {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }
}

/// A one-way wire of limited capacity with faults on the bytes passing through.
struct Wire {
    bytes: Vec<u8>,
    capacity: usize,
    corrupt: f64,
    drop: f64,
    dup: f64,
}

impl Wire {
    fn write(&mut self, rng: &mut Rng, frame: &[u8]) -> bool {
        if self.bytes.len() + frame.len() > self.capacity {
            return false;
        }
        if rng.chance(self.drop) {
            return true; // lost on the wire
        }
        let mut f = frame.to_vec();
        for b in f.iter_mut() {
            if rng.chance(self.corrupt) {
                *b ^= 1 << (rng.next() % 8);
            }
        }
        self.bytes.extend_from_slice(&f);
        if rng.chance(self.dup) {
            self.bytes.extend_from_slice(&f);
        }
        true
    }
}

fn msg(i: u32) -> Message {
    Message::Retire(Retire {
        pixel: i,
        rgb: [i, i ^ 7, 3],
        credit: u64::from(i) << 20,
        spawned: (i % 5) as u8,
    })
}

fn run(seed: u64, corrupt: f64, drop: f64, dup: f64, count: u32) -> (u64, node_fw::reliable::ChannelStats) {
    let mut rng = Rng(seed | 1);
    let mut a: Channel<8> = Channel::new(400);
    let mut b: Channel<8> = Channel::new(400);
    let new_wire = || Wire { bytes: Vec::new(), capacity: 600, corrupt, drop, dup };
    let (mut ab, mut ba) = (new_wire(), new_wire());
    let (mut sent, mut got_b, mut got_a) = (0u32, Vec::new(), Vec::new());
    let mut back = 0u32;
    let mut now = 0u64;
    while (got_b.len() as u32) < count || (got_a.len() as u32) < count / 4 {
        now += 1;
        assert!(now < 2_000_000, "no progress: {} of {count} delivered", got_b.len());
        while sent < count && a.send(msg(sent)).is_ok() {
            sent += 1;
        }
        while back < count / 4 && b.send(msg(1_000_000 + back)).is_ok() {
            back += 1;
        }
        a.transmit(now, |f| ab.write(&mut rng, f));
        b.transmit(now, |f| ba.write(&mut rng, f));
        // The wire delivers a few bytes per tick.
        let n = ab.bytes.len().min(40);
        let chunk: Vec<u8> = ab.bytes.drain(..n).collect();
        b.receive(&chunk, |m| {
            got_b.push(m);
            true
        });
        let n = ba.bytes.len().min(40);
        let chunk: Vec<u8> = ba.bytes.drain(..n).collect();
        a.receive(&chunk, |m| {
            got_a.push(m);
            true
        });
    }
    assert_eq!(got_b, (0..count).map(msg).collect::<Vec<_>>(), "A to B: every message once, in order");
    assert_eq!(got_a, (0..count / 4).map(|i| msg(1_000_000 + i)).collect::<Vec<_>>(), "B to A");
    (now, a.stats)
}

#[test]
fn clean_wire_needs_no_retransmission() {
    let (_, stats) = run(1, 0.0, 0.0, 0.0, 2000);
    assert_eq!(stats.retransmitted, 0);
}

#[test]
fn one_percent_corruption_and_drops_lose_nothing() {
    for seed in 1..6 {
        let (_, stats) = run(seed, 0.01 / 60.0, 0.01, 0.0, 3000);
        assert!(stats.retransmitted > 0, "seed {seed}: faults must have cost retransmissions");
    }
}

#[test]
fn heavy_faults_and_duplicates_lose_nothing() {
    for seed in 10..14 {
        run(seed, 0.002, 0.05, 0.05, 1500);
    }
}

#[test]
fn sequence_numbers_wrap() {
    // More than 2^16 messages through one channel.
    run(7, 0.0005, 0.01, 0.01, 70_000);
}

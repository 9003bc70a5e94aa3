//! The reliable channel over a wire that corrupts, drops and duplicates bytes:
//! every message arrives once, in order.

use link_proto::{Message, Retire, Retirements};
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
    Message::Retire(Retirements::new(Retire {
        pixel: i,
        rgb: [i, i ^ 7, 3],
        credit: u64::from(i) << 20,
        spawned: (i % 5) as u8,
        rays: 1,
        background: (i % 2) as u8,
    }))
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
    // Sequence numbers wrap every 256 frames: several times over, with losses.
    run(7, 0.0005, 0.01, 0.01, 5_000);
}

/// Runs `a` and `b` over a clean wire for `ticks` ticks from `*now`,
/// collecting what each delivers.
fn exchange(
    a: &mut Channel<4>,
    b: &mut Channel<4>,
    now: &mut u64,
    got_a: &mut Vec<Message>,
    got_b: &mut Vec<Message>,
) {
    for _ in 0..50 {
        *now += 1;
        let (mut ab, mut ba) = (Vec::new(), Vec::new());
        a.transmit(*now, |f| {
            ab.extend_from_slice(f);
            true
        });
        b.transmit(*now, |f| {
            ba.extend_from_slice(f);
            true
        });
        b.receive(&ab, |m| {
            got_b.push(m);
            true
        });
        a.receive(&ba, |m| {
            got_a.push(m);
            true
        });
    }
}

fn pair() -> (Channel<4>, Channel<4>) {
    let (mut a, mut b) = (Channel::new(5), Channel::new(5));
    a.set_incarnation(11);
    b.set_incarnation(70);
    (a, b)
}

#[test]
fn a_restarted_peer_is_noticed_and_both_streams_start_again() {
    let (mut a, mut b) = pair();
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    for i in 0..3 {
        a.send(msg(i)).unwrap();
    }
    b.send(msg(100)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert_eq!((got_a.len(), got_b.len()), (1, 3));

    // B restarts: fresh state, a new incarnation. A has one frame in flight for it.
    b = Channel::new(5);
    b.set_incarnation(71);
    let (mut got_a, mut got_b) = (Vec::new(), Vec::new());
    a.send(msg(3)).unwrap();
    b.send(msg(101)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);

    assert!(a.take_peer_restart(), "A must notice the new incarnation");
    assert!(!a.take_peer_restart(), "and report it once");
    assert!(!b.take_peer_restart(), "a fresh B had no earlier peer to lose");
    assert_eq!(a.stats.peer_restarts, 1);
    assert_eq!(got_a, vec![msg(101)], "the new B's stream reaches A from its first frame");
    assert_eq!(got_b, vec![msg(3)], "A's unacknowledged frame reaches the new B, renumbered");
    assert!(!a.busy() && !b.busy(), "both windows drained");
}

#[test]
fn a_restarted_end_with_nothing_to_send_announces_itself_to_the_old_stream() {
    let (mut a, mut b) = pair();
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    a.send(msg(0)).unwrap();
    b.send(msg(100)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);

    // B restarts with nothing of its own to send: a board that waits for
    // its host. A's stream to the old B would go unanswered for ever.
    b = Channel::new(5);
    b.set_incarnation(71);
    let mut got_b = Vec::new();
    a.send(msg(1)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert!(a.take_peer_restart(), "A learns of the restart from B's Sync");
    assert_eq!(got_b, vec![msg(1)], "and its frame reaches the new B");
    assert!(!a.busy() && !b.busy());
}

#[test]
fn a_late_copy_of_a_sync_resets_nothing() {
    let (mut a, mut b) = pair();
    // Catch B's first words: its `Sync`.
    b.send(msg(100)).unwrap();
    let mut sync = Vec::new();
    b.transmit(1, |f| {
        sync.extend_from_slice(f);
        true
    });
    let (mut now, mut got_a, mut got_b) = (1, Vec::new(), Vec::new());
    a.receive(&sync, |m| {
        got_a.push(m);
        true
    });
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    for i in 0..3 {
        b.send(msg(101 + i)).unwrap();
    }
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    // The copy arrives late, after the stream has moved on.
    a.receive(&sync, |m| {
        got_a.push(m);
        true
    });
    b.send(msg(104)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);

    assert!(!a.take_peer_restart());
    assert_eq!(got_a, (100..105).map(msg).collect::<Vec<_>>(), "each message once, in order");
}

#[test]
fn no_data_is_taken_before_the_peers_sync() {
    let (mut a, mut b) = pair();
    a.send(msg(0)).unwrap();
    // A data frame as an unsynchronised sender would put it on the wire.
    let mut frame = [0u8; link_proto::MAX_FRAME_LEN];
    let n = link_proto::encode_frame(&link_proto::Frame::new(0, msg(9)), &mut frame).unwrap();
    let mut got_b = Vec::new();
    b.receive(&frame[..n], |m| {
        got_b.push(m);
        true
    });
    assert!(got_b.is_empty());
    assert_eq!(b.stats.discarded, 1);
    let (mut now, mut got_a) = (0, Vec::new());
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert_eq!(got_b, vec![msg(0)]);
}

/// The frames `c` writes at `now`, decoded.
fn written(c: &mut Channel<4>, now: u64) -> (Vec<u8>, Vec<link_proto::Frame>) {
    let mut bytes = Vec::new();
    c.transmit(now, |f| {
        bytes.extend_from_slice(f);
        true
    });
    let mut dec = link_proto::FrameDecoder::new();
    let mut rest = &bytes[..];
    let frames = std::iter::from_fn(|| dec.decode(&mut rest)).map(Result::unwrap).collect();
    (bytes, frames)
}

#[test]
fn an_ack_rides_on_the_reply_and_takes_a_frame_only_without_one() {
    let (mut a, mut b) = pair();
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    // Both streams synchronised, nothing owed.
    a.send(msg(0)).unwrap();
    b.send(msg(100)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert!(!a.busy() && !b.busy());

    // A request, and B's reply to it: one frame each way, the reply carrying
    // B's acknowledgement of the request.
    a.send(msg(1)).unwrap();
    let (request, frames) = written(&mut a, now + 1);
    assert_eq!(frames.len(), 1);
    let request_seq = frames[0].seq;
    b.receive(&request, |_| true);
    b.send(msg(101)).unwrap();
    let (reply, frames) = written(&mut b, now + 2);
    assert_eq!(frames.len(), 1, "no ack frame beside the reply");
    assert_eq!((&frames[0].msg, frames[0].ack), (&msg(101), Some(request_seq)));
    a.receive(&reply, |_| true);

    // A has nothing to send back: its ack of the reply takes a frame. Past
    // A's time-out, that is all it writes: the request left its window.
    let (_, frames) = written(&mut a, now + 20);
    assert_eq!(frames.len(), 1, "{frames:?}");
    assert!(matches!(frames[0].msg, Message::Ack(_)) && frames[0].ack.is_none());
    assert_eq!(a.stats.retransmitted, 0);
}

#[test]
fn a_one_way_stream_is_acknowledged_once_per_half_window() {
    // A long resend time-out, so only the half-window rule can send acks.
    let (mut a, mut b) = (Channel::<4>::new(1_000), Channel::<4>::new(1_000));
    a.set_incarnation(1);
    b.set_incarnation(2);
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    a.send(msg(0)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    // B's ack of that first frame waits out a quarter of the time-out.
    now += 250;
    let (back, _) = written(&mut b, now);
    a.receive(&back, |_| true);
    assert!(!a.busy() && !b.busy());

    let mut acks = 0;
    for k in 1..=12 {
        a.send(msg(k)).unwrap();
        let (frames, _) = written(&mut a, now);
        b.receive(&frames, |m| {
            got_b.push(m);
            true
        });
        let (back, decoded) = written(&mut b, now);
        acks += decoded.iter().filter(|f| matches!(f.msg, Message::Ack(_))).count();
        a.receive(&back, |_| true);
        now += 1;
        assert!(a.can_send(), "the window never fills while acks wait");
    }
    assert_eq!(acks, 6, "12 frames, an ack for every 2");
    assert_eq!(got_b.len(), 13);
    assert_eq!(a.stats.retransmitted, 0);

    // One frame alone is answered once it has waited a quarter of the
    // time-out, long before the sender would resend it.
    a.send(msg(13)).unwrap();
    let (frames, _) = written(&mut a, now);
    b.receive(&frames, |_| true);
    assert!(written(&mut b, now + 200).1.is_empty(), "held");
    let (back, decoded) = written(&mut b, now + 250);
    assert!(matches!(decoded.as_slice(), [f] if f.msg == Message::Ack(13)), "{decoded:?}");
    a.receive(&back, |_| true);
    assert!(!a.busy());
}

#[test]
fn resends_back_off_while_the_peer_stays_silent_and_recover_on_an_ack() {
    let (mut a, mut b) = (Channel::<4>::new(100), Channel::<4>::new(100));
    a.set_incarnation(1);
    b.set_incarnation(2);
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    a.send(msg(0)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert!(!a.busy());

    // A frame into silence: its copies go out after 100, then 200, 400, 800
    // and 1 600 ticks more, and then every 1 600 (the backoff's cap).
    let start = now;
    a.send(msg(1)).unwrap();
    let (mut sent_at, mut last_copy) = (Vec::new(), Vec::new());
    for t in start..start + 5_000 {
        let (bytes, frames) = written(&mut a, t);
        if frames.iter().any(|f| f.msg == msg(1)) {
            sent_at.push(t - start);
            last_copy = bytes;
        }
    }
    assert_eq!(sent_at, [0, 100, 300, 700, 1_500, 3_100, 4_700]);
    assert_eq!(a.stats.retransmitted, 6);

    // The peer answers at last: the next frame is resent after one
    // time-out again.
    let mut ack = Vec::new();
    b.receive(&last_copy, |_| true);
    for t in 0..100 {
        ack.extend(written(&mut b, start + 4_700 + t).0);
    }
    a.receive(&ack, |_| true);
    assert!(!a.busy(), "acknowledged");
    let again = start + 5_000;
    a.send(msg(2)).unwrap();
    assert!(written(&mut a, again).1.iter().any(|f| f.msg == msg(2)));
    assert!(!written(&mut a, again + 99).1.iter().any(|f| f.msg == msg(2)), "not before the time-out");
    assert!(written(&mut a, again + 100).1.iter().any(|f| f.msg == msg(2)), "resent after one time-out");
}

#[test]
fn frames_due_together_leave_in_one_and_one_refused_waits_for_room() {
    let (mut a, mut b) = pair();
    let (mut now, mut got_a, mut got_b) = (0, Vec::new(), Vec::new());
    a.send(msg(0)).unwrap();
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert!(!a.busy() && !b.busy());

    for k in 1..=3 {
        a.send(msg(k)).unwrap();
    }
    let (bytes, frames) = written(&mut a, now + 1);
    assert_eq!(bytes.iter().filter(|&&b| b == 0).count(), 1, "one frame, one delimiter");
    let first = frames[0].seq;
    let numbered: Vec<_> = frames.iter().map(|f| (f.seq, f.msg.clone())).collect();
    assert_eq!(numbered, (1..=3).map(|k| (first + k as u8 - 1, msg(k))).collect::<Vec<_>>());

    // B's inbox takes two: the third waits in B's decoder, no byte read
    // after it, until a receive with none finds room; nothing is resent.
    let mut room = 2;
    b.receive(&bytes, |m| {
        if room == 0 {
            return false;
        }
        room -= 1;
        got_b.push(m);
        true
    });
    assert!(b.holds_back());
    b.receive(&[], |_| false);
    assert!(b.holds_back(), "still no room");
    b.receive(&[], |m| {
        got_b.push(m);
        true
    });
    assert!(!b.holds_back());
    exchange(&mut a, &mut b, &mut now, &mut got_a, &mut got_b);
    assert_eq!(got_b, (0..=3).map(msg).collect::<Vec<_>>(), "each once, in order");
    assert_eq!(a.stats.retransmitted, 0);
}

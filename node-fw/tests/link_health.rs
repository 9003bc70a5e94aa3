//! A node tells the host of the frames that reached it damaged and the bytes
//! its receivers lost, per port, before its final load report, and only what
//! happened since it last told.
//! The damage is made here, a byte flipped in chosen frames on the way in,
//! so the counts the report must carry are known without asking the node.

use link_proto::{Finish, Hello, LinkHealth, Message, PortHealth};
use node_fw::framed::FramedLinks;
use node_fw::node::Node;
use node_fw::reliable::Channel;
use node_fw::{Links, Port};

type TestNode = Node<8, 64, 64, 16, 8>;
type TestLinks = FramedLinks<4, 4>;

/// The host's incarnation, which is the session its nodes are in.
const SESSION: u32 = 500;

/// A node with its host and its +x neighbour, every wire between them
/// carried by hand.
struct Bench {
    node: TestNode,
    links: TestLinks,
    host: Channel<4>,
    neighbour: Channel<4>,
    now: u64,
}

impl Bench {
    fn new() -> Self {
        let mut links = TestLinks::new(5);
        links.set_incarnation(1);
        let mut host = Channel::new(5);
        host.set_incarnation(SESSION);
        let mut neighbour = Channel::new(5);
        neighbour.set_incarnation(40);
        let mut bench = Self { node: TestNode::new(0), links, host, neighbour, now: 0 };
        assert_eq!(bench.host.send(Message::Hello(Hello::host())), Ok(()));
        bench.run(&mut |_| false);
        let hello = Hello { node: 1, capacity: TestNode::capacity(), session: SESSION, ..Hello::host() };
        assert_eq!(bench.neighbour.send(Message::Hello(hello)), Ok(()));
        bench.run(&mut |_| false);
        bench
    }

    /// Moves bytes for a while; `damage` says which of the frames the
    /// neighbour sends in this run (counted from 0) to damage.
    /// Returns what the host received.
    fn run(&mut self, damage: &mut impl FnMut(usize) -> bool) -> Vec<Message> {
        let mut got = Vec::new();
        let mut frames = 0;
        for _ in 0..200 {
            self.now += 1;
            self.node.poll(self.now, &mut self.links);
            let (mut to_host, mut to_neighbour) = (Vec::new(), Vec::new());
            self.links.transmit(self.now, |p, bytes| {
                match p {
                    Port::Host => to_host.extend_from_slice(bytes),
                    Port::PosX => to_neighbour.extend_from_slice(bytes),
                    _ => {}
                }
                true
            });
            let mut from_host = Vec::new();
            self.host.transmit(self.now, |b| {
                from_host.extend_from_slice(b);
                true
            });
            self.links.ingest(Port::Host, &from_host);
            let mut from_neighbour = Vec::new();
            self.neighbour.transmit(self.now, |b| {
                let mut frame = b.to_vec();
                if damage(frames) {
                    flip_a_byte(&mut frame);
                }
                frames += 1;
                from_neighbour.extend_from_slice(&frame);
                true
            });
            self.links.ingest(Port::PosX, &from_neighbour);
            self.host.receive(&to_host, |m| {
                got.push(m);
                true
            });
            self.neighbour.receive(&to_neighbour, |_| true);
        }
        got
    }

    /// The host ends a frame; what the node says before its final load.
    fn finish(&mut self) -> Vec<LinkHealth> {
        assert_eq!(self.host.send(Message::Finish(Finish { frame: 0 })), Ok(()));
        let got = self.run(&mut |_| false);
        let load = got.iter().position(|m| matches!(m, Message::Load(_))).expect("a final load report");
        got[..load]
            .iter()
            .filter_map(|m| match m {
                Message::LinkHealth(h) => Some(*h),
                _ => None,
            })
            .collect()
    }
}

/// Damages a frame written as `0x00 ++ COBS ++ 0x00` without making a new
/// delimiter: the byte stays non-zero, so the frame stays one damaged frame.
fn flip_a_byte(frame: &mut [u8]) {
    let inner = frame.len() - 2;
    let i = 1 + inner / 2;
    assert!(inner >= 3 && frame[i] != 0);
    frame[i] ^= if frame[i] == 0x80 { 0x40 } else { 0x80 };
}

/// What the node counts on each port, read from its links directly.
fn counted(links: &TestLinks) -> [PortHealth; 7] {
    Port::ALL.map(|p| links.health(p))
}

#[test]
fn clean_links_send_no_report() {
    let mut bench = Bench::new();
    assert_eq!(bench.finish(), vec![], "nothing was damaged or resent");
}

#[test]
fn damaged_frames_are_told_once_before_the_final_load() {
    let mut bench = Bench::new();
    for _ in 0..4 {
        assert_eq!(bench.neighbour.send(Message::Space), Ok(()));
    }
    // The four leave in one batch: it and its first resend damaged.
    bench.run(&mut |n| n == 0 || n == 1);
    let reports = bench.finish();
    assert_eq!(reports.len(), 1, "{reports:?}");
    let told = reports[0];
    assert_eq!(told.node, 0);
    assert_eq!(told.ports[Port::PosX.index()].damaged, 2, "{told:?}");
    assert_eq!(told.ports, counted(&bench.links), "the report carries every count since the start");

    // Nothing new: no report. Then one more damaged frame: only that one.
    assert_eq!(bench.finish(), vec![]);
    assert_eq!(bench.neighbour.send(Message::Space), Ok(()));
    bench.run(&mut |n| n == 0);
    let reports = bench.finish();
    assert_eq!(reports.len(), 1, "{reports:?}");
    let mut expected = [PortHealth::default(); 7];
    expected[Port::PosX.index()].damaged = 1;
    let resent_since = counted(&bench.links).map(|p| p.resent);
    let resent_before = told.ports.map(|p| p.resent);
    for (e, (now, before)) in expected.iter_mut().zip(resent_since.iter().zip(resent_before)) {
        e.resent = now - before;
    }
    assert_eq!(reports[0].ports, expected);
}

#[test]
fn bytes_a_receiver_lost_are_told_as_counted_since_the_last_report() {
    let mut bench = Bench::new();
    // The board's UART driver counts 3 bytes lost on -y, then 2 more.
    bench.links.note_lost(Port::NegY, 3);
    let reports = bench.finish();
    assert_eq!(reports.len(), 1, "{reports:?}");
    let mut expected = [PortHealth::default(); 7];
    expected[Port::NegY.index()].lost = 3;
    assert_eq!(reports[0].ports, expected);
    bench.links.note_lost(Port::NegY, 2);
    expected[Port::NegY.index()].lost = 2;
    assert_eq!(bench.finish().iter().map(|r| r.ports).collect::<Vec<_>>(), vec![expected]);
    assert_eq!(bench.finish(), vec![], "nothing new");
}

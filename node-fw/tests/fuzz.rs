//! Fuzzing at volume (proptest): the node firmware never panics on any input
//! and never grows without bound. Tests run with overflow checks on, so an
//! arithmetic overflow is a panic here too.

mod common;

use link_proto::*;
use node_fw::{Links, Node, Port};
use proptest::prelude::*;

type Fw = Node<64, 512, 512, 256, 128>;

/// Links that deliver a scripted list of messages and record everything sent.
#[derive(Default)]
struct Script {
    inbox: Vec<(Port, Message)>,
    sent: usize,
    /// Of those, rays (a cost model charges them apart).
    rays_sent: usize,
    rays_received: usize,
    full: bool,
    /// Peers that restart (a new incarnation on a framed link), one per poll.
    restarts: Vec<Port>,
}

/// Polls `node` once and checks its work report against what the links saw:
/// exactly the messages they took and gave, rays apart (a cost model charges
/// by them), and sends bounded by what the node can hold, not by its input.
fn poll_counted(node: &mut Fw, links: &mut Script, now: u64) -> Result<node_fw::Work, TestCaseError> {
    let before = (links.sent, links.rays_sent, links.rays_received);
    let work = node.poll(now, links);
    let sent = links.sent - before.0;
    prop_assert_eq!(work.sent as usize, sent);
    prop_assert_eq!(work.rays_sent as usize, links.rays_sent - before.1);
    prop_assert_eq!(work.rays_received as usize, links.rays_received - before.2);
    prop_assert!(sent <= 256 + 64 + 16 + 16, "sent {} in one poll", sent);
    Ok(work)
}

/// The ports whose peers restart at `step`.
fn due(restarts: &[(u64, Port)], step: u64) -> Vec<Port> {
    restarts.iter().filter(|(at, _)| *at == step).map(|(_, p)| *p).collect()
}

impl Links for Script {
    fn recv(&mut self, port: Port) -> Option<Message> {
        let i = self.inbox.iter().position(|(p, _)| *p == port)?;
        let msg = self.inbox.remove(i).1;
        self.rays_received += usize::from(msg.is_ray());
        Some(msg)
    }
    fn try_send(&mut self, _: Port, msg: Message) -> Result<(), Message> {
        if self.full {
            return Err(msg);
        }
        self.sent += 1;
        self.rays_sent += usize::from(msg.is_ray());
        Ok(())
    }
    fn peer_restarted(&mut self) -> Option<Port> {
        self.restarts.pop()
    }
}

fn arb_port() -> impl Strategy<Value = Port> {
    (0usize..7).prop_map(|i| Port::ALL[i])
}

fn small_i32() -> impl Strategy<Value = i32> {
    prop_oneof![any::<i32>(), -(20 << 16)..(20 << 16), Just(0), Just(i32::MIN), Just(i32::MAX)]
}

fn arb_sphere() -> impl Strategy<Value = SphereMsg> {
    (any::<u16>(), proptest::array::uniform3(small_i32()), small_i32(), any::<[u16; 3]>(), any::<u8>())
        .prop_map(|(id, center, radius, color, shininess)| SphereMsg {
            id,
            center,
            radius,
            material: MaterialMsg {
                color,
                ambient: 9000,
                diffuse: 20000,
                specular: 8000,
                shininess,
                reflect: 12000,
            },
        })
}

fn arb_ray() -> impl Strategy<Value = RayMsg> {
    (
        proptest::array::uniform3(small_i32()),
        proptest::array::uniform3(any::<i32>()),
        proptest::array::uniform3(0u16..20),
        any::<u16>(),
        prop_oneof![Just(RayKind::Primary), Just(RayKind::Reflected), Just(RayKind::Shadow)],
        proptest::option::of((small_i32(), arb_sphere())),
        proptest::option::of(small_i32()),
    )
        .prop_map(|(origin, dir, cell, class, kind, best, t_max)| RayMsg {
            origin,
            dir,
            cell,
            pixel: class.into(),
            weight: [32768; 3],
            credit: 1 << 20,
            kind,
            depth: (class % 4) as u8,
            ignore: None,
            best: best.map(|(t, sphere)| HitMsg { t, sphere }),
            t_max,
            class: class % 40,
            tag: class,
        })
}

/// Messages a node may see: well-formed scene traffic and arbitrary junk.
fn arb_message() -> impl Strategy<Value = Message> {
    let camera = proptest::array::uniform4(proptest::array::uniform3(small_i32()))
        .prop_map(|[eye, corner, du, dv]| CameraMsg { eye, corner, du, dv });
    prop_oneof![
        3 => (proptest::array::uniform3(0u16..20), any::<u8>(), any::<bool>()).prop_map(|(grid, max_depth, kept)| Message::SceneBegin(SceneHeader {
            grid,
            ambient: [8000; 3],
            background: [1000; 3],
            max_depth: max_depth % 6,
            map: if kept { link_proto::MapLoad::Kept } else { link_proto::MapLoad::Sent },
        })),
        3 => (proptest::array::uniform3(0u16..4), proptest::array::uniform3(0u16..20), proptest::array::uniform3(0u16..20), 0u8..4)
            .prop_map(|(array, lo, hi, driving_axis)| Message::Assign(Assign {
                array,
                coord: [0; 3],
                lo,
                hi,
                driving_axis,
                boundaries: if driving_axis == 1 { Boundaries::StaggeredRows } else { Boundaries::Whole },
            })),
        4 => arb_sphere().prop_map(Message::Sphere),
        1 => (proptest::array::uniform3(small_i32()), any::<u8>())
            .prop_map(|(position, id)| Message::Light(LightMsg { id, position, color: [20000; 3] })),
        2 => (0u32..30, 0u8..3, 0u16..3).prop_map(|(spheres, lights, occupancy)| Message::SceneEnd(SceneEnd { spheres, lights, occupancy })),
        2 => (prop_oneof![Just(0u32), Just(256), Just(512), any::<u32>()], any::<[u8; 32]>())
            .prop_map(|(first, bits)| Message::Occupancy(OccupancyMsg { first, bits })),
        2 => (camera, any::<[u16; 2]>(), any::<[u16; 4]>(), (0u16..6, proptest::option::of(any::<u16>())), any::<bool>()).prop_map(
            |(camera, size, tile, (level_depth, shared_slots), balance)| Message::RenderStart(RenderStart {
                frame: 0,
                size: [size[0] % 64, size[1] % 64],
                camera,
                initial: InitialRays::Parallel,
                tile: tile.map(|t| t % 64),
                credit: 1 << 32,
                level_depth,
                shared_slots,
                balance: balance.then_some(Balance { interval: 50, threshold: 1 << 16, step: 1, policy: SlidePolicy::Paper }),
            })
        ),
        6 => arb_ray().prop_map(Message::Ray),
        3 => arb_ray().prop_map(Message::GrantedRay),
        2 => any::<u16>().prop_map(Message::Grant),
        2 => (any::<u16>(), any::<bool>()).prop_map(|(tag, accepted)| Message::RayReply(RayReply { tag, accepted })),
        1 => Just(Message::Space),
        1 => (any::<u32>(), any::<u64>(), any::<u64>(), any::<u16>()).prop_map(|(interval, running, waiting, extent)| {
            Message::Load(LoadReport { node: 0, interval, running, waiting, rays: 0, sphere_tests: 0, cube_steps: 0, refused: 0, extent, busy_polls: 0 })
        }),
        1 => (any::<u32>(), any::<u16>()).prop_map(|(interval, boundary)| Message::SlideOffer(SlideOffer { interval, boundary })),
        1 => (any::<u32>(), any::<u16>()).prop_map(|(interval, boundary)| Message::SlideRequest(SlideOffer { interval, boundary })),
        1 => (any::<u16>(), any::<u32>()).prop_map(|(boundary, spheres)| Message::SlideDone(SlideDone { boundary, spheres })),
        1 => any::<u16>().prop_map(|boundary| Message::SlideReply(SlideReply { boundary, refused: None })),
        1 => any::<u32>().prop_map(|frame| Message::Finish(Finish { frame })),
        1 => (prop_oneof![Just(PROTOCOL_VERSION), any::<u16>()], prop_oneof![Just(0u32), any::<u32>()]).prop_map(|(version, session)| {
            Message::Hello(Hello { version, node: 1, capacity: Fw::capacity(), session, ..Hello::host() })
        }),
        1 => any::<link_proto::Seq>().prop_map(Message::Ack),
        1 => any::<link_proto::Seq>().prop_map(Message::Nak),
        1 => any::<u32>().prop_map(Message::Sync),
        1 => any::<u32>().prop_map(Message::SyncAck),
    ]
}

/// `script` after a hello from every neighbour, as on a real link: a
/// neighbour's messages reach the node only after its hello of the node's
/// session (some hellos in the script name other sessions, and what follows
/// them is dropped).
fn greeted(script: Vec<(Port, Message)>) -> Vec<(Port, Message)> {
    let hello = Message::Hello(Hello { node: 1, capacity: Fw::capacity(), ..Hello::host() });
    let mut inbox: Vec<(Port, Message)> = Port::NEIGHBOURS.iter().map(|&p| (p, hello.clone())).collect();
    inbox.extend(script);
    inbox
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary message sequences on arbitrary ports, with links that are
    /// sometimes full: the node never panics, and its work per poll is bounded.
    #[test]
    fn node_survives_arbitrary_message_sequences(
        script in proptest::collection::vec((arb_port(), arb_message()), 1..60),
        full_every in 2usize..6,
        restarts in proptest::collection::vec((0u64..200, arb_port()), 0..3),
    ) {
        let mut node: Box<Fw> = Box::new(Fw::new(3));
        let mut links = Script { inbox: greeted(script), ..Script::default() };
        for step in 0..200u64 {
            links.full = (step as usize).is_multiple_of(full_every);
            links.restarts = due(&restarts, step);
            let work = poll_counted(&mut node, &mut links, step * 100)?;
            prop_assert!(work.traces <= 1 && work.created <= 1);
            if links.inbox.is_empty() && !node.pending() {
                break;
            }
        }
    }

    /// Arbitrary well-formed frames into a reliable channel (acks, naks,
    /// syncs of any incarnation, data out of order): never a panic, and what
    /// it writes per transmit stays within its window and control frames.
    #[test]
    fn channel_survives_arbitrary_frames(
        frames in proptest::collection::vec((any::<link_proto::Seq>(), arb_message()), 1..80),
        sends in 0usize..8,
    ) {
        let mut channel: node_fw::reliable::Channel<4> = node_fw::reliable::Channel::new(3);
        channel.set_incarnation(5);
        for i in 0..sends {
            let _ = channel.send(Message::Finish(Finish { frame: i as u32 }));
        }
        let mut buf = [0u8; MAX_FRAME_LEN];
        for (now, (seq, msg)) in frames.into_iter().enumerate() {
            let n = encode_frame(&Frame::new(seq, msg), &mut buf).unwrap();
            channel.receive(&buf[..n], |_| now % 3 != 0);
            let mut written = 0;
            channel.transmit(now as u64, |bytes| {
                written += bytes.len();
                true
            });
            prop_assert!(written <= (4 + 3) * MAX_FRAME_LEN, "wrote {written} bytes at once");
            let _ = channel.take_peer_restart();
        }
    }

    /// Arbitrary bytes into the frame decoder: never a panic, at most one
    /// error per delimiter, and the second valid frame after the junk
    /// decodes (the first goes with junk that runs into it).
    #[test]
    fn decoder_survives_arbitrary_bytes(junk in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut dec = FrameDecoder::new();
        let zeros = junk.iter().filter(|&&b| b == 0).count();
        let errors = decode_each(&mut dec, &junk).iter().filter(|r| r.is_err()).count();
        prop_assert!(errors <= zeros + junk.len() / MAX_FRAME_LEN + 1);
        let mut out = [0u8; MAX_FRAME_LEN];
        let frame = Frame::new(9, Message::Space);
        let n = encode_frame(&frame, &mut out).unwrap();
        let _ = decode_each(&mut dec, &out[..n]);
        prop_assert_eq!(decode_each(&mut dec, &out[..n]), vec![Ok(frame)]);
    }
}

/// Every result `bytes` lead `dec` to.
fn decode_each(dec: &mut FrameDecoder, mut bytes: &[u8]) -> Vec<Result<Frame, link_proto::DecodeError>> {
    std::iter::from_fn(|| dec.decode(&mut bytes)).collect()
}

/// A well-formed scene and render start, so the fuzzed tail reaches a rendering node.
fn valid_setup(spheres: &[SphereMsg]) -> Vec<(Port, Message)> {
    let mut v = vec![
        (
            Port::Host,
            Message::SceneBegin(SceneHeader {
                grid: [8; 3],
                ambient: [8000; 3],
                background: [500; 3],
                max_depth: 2,
                map: link_proto::MapLoad::Sent,
            }),
        ),
        (
            Port::Host,
            Message::Assign(Assign {
                array: [1, 1, 1],
                coord: [0; 3],
                lo: [0; 3],
                hi: [8, 8, 8],
                driving_axis: 0,
                boundaries: Boundaries::Whole,
            }),
        ),
    ];
    let mut n = 0;
    for s in spheres {
        v.push((Port::Host, Message::Sphere(*s)));
        n += 1;
    }
    v.push((
        Port::Host,
        Message::Light(LightMsg { id: 0, position: [4 << 16, 20 << 16, -(10 << 16)], color: [30000; 3] }),
    ));
    v.push((Port::Host, Message::SceneEnd(SceneEnd { spheres: n, lights: 1, occupancy: 0 })));
    v.push((
        Port::Host,
        Message::RenderStart(common::render_start(Balance {
            interval: 500,
            threshold: 1 << 16,
            step: 1,
            policy: SlidePolicy::Paper,
        })),
    ));
    v
}

fn inside_sphere() -> impl Strategy<Value = SphereMsg> {
    (0u16..50, proptest::array::uniform3(1i32..7), 1i32..64).prop_map(|(id, c, r)| SphereMsg {
        id,
        center: c.map(|x| x << 16),
        radius: r << 10,
        material: MaterialMsg {
            color: [20000; 3],
            ambient: 9000,
            diffuse: 20000,
            specular: 8000,
            shininess: 8,
            reflect: 16000,
        },
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

    /// A rendering node fed arbitrary neighbour and host traffic.
    #[test]
    fn rendering_node_survives_arbitrary_traffic(
        spheres in proptest::collection::vec(inside_sphere(), 0..12),
        tail in proptest::collection::vec((arb_port(), arb_message()), 0..40),
        full_every in 2usize..6,
        restarts in proptest::collection::vec((0u64..400, arb_port()), 0..2),
    ) {
        let mut script = valid_setup(&spheres);
        script.extend(tail);
        let mut node: Box<Fw> = Box::new(Fw::new(0));
        let mut links = Script { inbox: greeted(script), ..Script::default() };
        for step in 0..400u64 {
            links.full = (step as usize).is_multiple_of(full_every);
            links.restarts = due(&restarts, step);
            poll_counted(&mut node, &mut links, step * 100)?;
            if links.inbox.is_empty() && !node.pending() {
                break;
            }
        }
    }
}

/// The fuzz fixture really renders: without junk, the node creates and retires
/// every pixel's ray (some sends are replies and hellos; at least 64 retire).
#[test]
fn the_valid_setup_renders() {
    let spheres = [SphereMsg {
        id: 1,
        center: [2 << 16, 4 << 16, 4 << 16],
        radius: 1 << 16,
        material: MaterialMsg {
            color: [20000; 3],
            ambient: 9000,
            diffuse: 20000,
            specular: 8000,
            shininess: 8,
            reflect: 0,
        },
    }];
    let mut node: Box<Fw> = Box::new(Fw::new(0));
    let mut links = Script { inbox: valid_setup(&spheres), ..Script::default() };
    let mut traces = 0;
    for step in 0..2000u64 {
        traces += node.poll(step * 100, &mut links).traces;
    }
    assert!(!node.failed());
    assert!(traces >= 64, "traced {traces} rays");
    assert!(links.sent >= 64, "sent {}", links.sent);
}

//! Round trips of every message, and detection of corruption at every byte.

use link_proto::*;
use proptest::prelude::*;

fn decode_all(dec: &mut FrameDecoder, bytes: &[u8]) -> Vec<Result<Frame, DecodeError>> {
    // A byte at a time, every result each leads to.
    let mut results = Vec::new();
    for b in bytes {
        let mut byte = std::slice::from_ref(b);
        while let Some(r) = dec.decode(&mut byte) {
            results.push(r);
        }
    }
    results
}

fn encode(frame: &Frame) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode_frame(frame, &mut out).unwrap();
    out[..n].to_vec()
}

fn arb_material() -> impl Strategy<Value = MaterialMsg> {
    (any::<[u16; 3]>(), any::<u16>(), any::<u16>(), any::<u16>(), any::<u8>(), any::<u16>()).prop_map(
        |(color, ambient, diffuse, specular, shininess, reflect)| MaterialMsg {
            color,
            ambient,
            diffuse,
            specular,
            shininess,
            reflect,
        },
    )
}

fn arb_ray() -> impl Strategy<Value = RayMsg> {
    (
        (any::<[i32; 3]>(), any::<[i32; 3]>(), any::<[u16; 3]>(), any::<u32>()),
        (any::<[u32; 3]>(), any::<u64>(), 0u8..3, any::<u8>()),
        (
            any::<Option<u16>>(),
            proptest::option::of((any::<i32>(), any::<u16>(), arb_material())),
            any::<Option<i32>>(),
        ),
    )
        .prop_map(
            |((origin, dir, cell, pixel), (weight, credit, kind, depth), (ignore, best, t_max))| RayMsg {
                origin,
                dir,
                cell,
                pixel,
                weight,
                credit,
                kind: [RayKind::Primary, RayKind::Reflected, RayKind::Shadow][kind as usize],
                depth,
                ignore,
                best: best.map(|(t, id, material)| HitMsg {
                    t,
                    sphere: SphereMsg { id, center: [t, -t, t / 3], radius: t / 7, material },
                }),
                t_max,
                class: credit as u16,
                tag: pixel as u16,
            },
        )
}

fn arb_error_code() -> impl Strategy<Value = ErrorCode> {
    prop_oneof![
        Just(ErrorCode::Version),
        Just(ErrorCode::BadFrame),
        Just(ErrorCode::Unexpected),
        Just(ErrorCode::SphereCapacity),
        Just(ErrorCode::RefCapacity),
        Just(ErrorCode::CubeCapacity),
        Just(ErrorCode::OutOfRange),
        Just(ErrorCode::BadRay),
        Just(ErrorCode::SceneCount),
        Just(ErrorCode::PoolCapacity),
        Just(ErrorCode::ClassOverflow),
    ]
}

/// Every variant of [`Message`], with arbitrary field values.
fn arb_message() -> impl Strategy<Value = Message> {
    let camera = (any::<[i32; 3]>(), any::<[i32; 3]>(), any::<[i32; 3]>(), any::<[i32; 3]>())
        .prop_map(|(eye, corner, du, dv)| CameraMsg { eye, corner, du, dv });
    prop_oneof![
        (any::<u16>(), any::<u16>(), any::<(u32, u32, u32, u16)>(), arb_board(), any::<u32>()).prop_map(
            |(version, node, c, board, session)| {
                Message::Hello(Hello {
                    version,
                    node,
                    capacity: Capacity { spheres: c.0, refs: c.1, cubes: c.2, rays: c.3 },
                    board,
                    session,
                })
            }
        ),
        (any::<[u16; 3]>(), any::<[u16; 3]>(), any::<[u16; 3]>(), any::<u8>(), any::<bool>()).prop_map(
            |(grid, ambient, background, max_depth, kept)| Message::SceneBegin(SceneHeader {
                grid,
                ambient,
                background,
                max_depth,
                map: if kept { link_proto::MapLoad::Kept } else { link_proto::MapLoad::Sent },
            })
        ),
        (any::<u16>(), any::<[i32; 3]>(), any::<i32>(), arb_material()).prop_map(
            |(id, center, radius, material)| { Message::Sphere(SphereMsg { id, center, radius, material }) }
        ),
        (any::<u8>(), any::<[i32; 3]>(), any::<[u16; 3]>())
            .prop_map(|(id, position, color)| { Message::Light(LightMsg { id, position, color }) }),
        (any::<u32>(), any::<u8>(), any::<u16>()).prop_map(|(spheres, lights, occupancy)| Message::SceneEnd(
            SceneEnd { spheres, lights, occupancy }
        )),
        (any::<u32>(), any::<[u8; 32]>())
            .prop_map(|(first, bits)| Message::Occupancy(OccupancyMsg { first, bits })),
        (any::<[[u16; 3]; 4]>(), any::<u8>()).prop_map(|(a, driving_axis)| Message::Assign(Assign {
            array: a[0],
            coord: a[1],
            lo: a[2],
            hi: a[3],
            driving_axis,
            boundaries: [Boundaries::Whole, Boundaries::StaggeredRows, Boundaries::StaggeredColumns]
                [usize::from(driving_axis % 3)],
        })),
        (any::<u32>(), any::<[u16; 2]>(), camera, any::<bool>(), any::<[u16; 4]>(), any::<u64>()).prop_map(
            |(frame, size, camera, eye, tile, credit)| Message::RenderStart(RenderStart {
                frame,
                size,
                camera,
                initial: if eye { InitialRays::EyeNode } else { InitialRays::Parallel },
                tile,
                credit,
                level_depth: frame as u16,
                shared_slots: (credit % 3 == 0).then_some(size[0]),
                balance: (credit % 2 == 0).then_some(Balance {
                    interval: credit,
                    threshold: frame,
                    step: 1,
                    policy: if frame % 2 == 0 {
                        SlidePolicy::Paper
                    } else {
                        SlidePolicy::Proportional { gamma: frame, deadband: frame / 3 }
                    },
                }),
            })
        ),
        arb_ray().prop_map(Message::Ray),
        proptest::collection::vec(
            (any::<u32>(), any::<[u32; 3]>(), any::<u64>(), any::<(u8, u8, u8)>()),
            1..=3
        )
        .prop_map(|records| {
            let mut all = records.into_iter().map(|(pixel, rgb, credit, (spawned, rays, background))| {
                Retire { pixel, rgb, credit, spawned, rays, background }
            });
            let mut batch = Retirements::new(all.next().unwrap_or_default());
            for r in all {
                let _ = batch.push(r);
            }
            Message::Retire(batch)
        }),
        (any::<(u16, u32, u64, u64)>(), any::<(u32, u32, u32)>()).prop_map(|(a, b)| Message::Load(
            LoadReport {
                node: a.0,
                interval: a.1,
                running: a.2,
                waiting: a.3,
                rays: b.0,
                sphere_tests: b.1,
                cube_steps: b.2,
                refused: b.0 ^ b.1,
                extent: b.2 as u16,
                busy_polls: b.1 ^ b.2,
            }
        )),
        (any::<u32>(), any::<u16>())
            .prop_map(|(interval, boundary)| Message::SlideOffer(SlideOffer { interval, boundary })),
        (any::<u16>(), 0u8..4).prop_map(|(boundary, r)| Message::SlideReply(SlideReply {
            boundary,
            refused: [
                None,
                Some(SlideRefusal::Capacity),
                Some(SlideRefusal::Empty),
                Some(SlideRefusal::Busy)
            ][r as usize],
        })),
        (any::<u16>(), any::<u32>())
            .prop_map(|(boundary, spheres)| Message::SlideDone(SlideDone { boundary, spheres })),
        any::<u32>().prop_map(|frame| Message::Finish(Finish { frame })),
        (any::<u16>(), arb_error_code(), any::<u32>(), any::<u32>())
            .prop_map(|(node, code, a, b)| Message::Error(ErrorReport { node, code, a, b })),
        any::<Seq>().prop_map(Message::Ack),
        any::<Seq>().prop_map(Message::Nak),
        (any::<u16>(), any::<bool>())
            .prop_map(|(tag, accepted)| Message::RayReply(RayReply { tag, accepted })),
        Just(Message::Space),
        (any::<u32>(), any::<u16>())
            .prop_map(|(interval, boundary)| Message::SlideRequest(SlideOffer { interval, boundary })),
        (any::<u8>(), any::<[u32; 3]>())
            .prop_map(|(port, id)| Message::Peer(PeerNote { port, board: BoardId(id) })),
        (any::<u16>(), any::<[(u32, u32, u32); 7]>()).prop_map(|(node, counts)| Message::LinkHealth(
            LinkHealth {
                node,
                ports: counts.map(|(resent, damaged, lost)| PortHealth { resent, damaged, lost })
            }
        )),
    ]
}

/// Any board a hello can describe.
fn arb_board() -> impl Strategy<Value = BoardInfo> {
    let kind = prop_oneof![
        Just(BoardKind::Host),
        Just(BoardKind::Simulated),
        Just(BoardKind::Mps2An385),
        Just(BoardKind::Netduinoplus2),
        Just(BoardKind::NucleoF413zh),
    ];
    let source = prop_oneof![
        Just(ClockSource::PllFromExternal),
        Just(ClockSource::PllFromInternal),
        Just(ClockSource::Reset),
        Just(ClockSource::Virtual),
    ];
    (any::<[u32; 3]>(), kind, any::<[u8; 3]>(), any::<[u32; 3]>(), source).prop_map(
        |(id, kind, [major, minor, patch], [clock_hz, link_baud, host_baud], clock_source)| BoardInfo {
            id: BoardId(id),
            kind,
            firmware: FirmwareVersion { major, minor, patch },
            clock_hz,
            clock_source,
            link_baud,
            host_baud,
        },
    )
}

fn arb_frame() -> impl Strategy<Value = Frame> {
    (any::<Seq>(), arb_message(), any::<Option<Seq>>()).prop_map(|(seq, msg, ack)| Frame { seq, msg, ack })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_message_round_trips(frame in arb_frame()) {
        let bytes = encode(&frame);
        prop_assert!(bytes.len() <= MAX_FRAME_LEN);
        prop_assert_eq!(*bytes.last().unwrap(), 0, "a frame ends at its delimiter");
        prop_assert!(!bytes[..bytes.len() - 1].contains(&0), "COBS leaves no zero before it");
        let mut dec = FrameDecoder::new();
        prop_assert_eq!(decode_all(&mut dec, &bytes), vec![Ok(frame)]);
    }

    /// A message kept in its wire form (a sender's window) is `wire`'s, and
    /// framed alone makes the message's frame.
    #[test]
    fn a_message_kept_in_its_wire_form_frames_as_itself(frame in arb_frame()) {
        let mut bytes = [0u8; MAX_MESSAGE_LEN];
        let n = encode_message(&frame.msg, &mut bytes).unwrap();
        prop_assert_eq!(&bytes[..n], &wire(&frame.msg)[..]);
        let mut out = [0u8; MAX_FRAME_LEN];
        let m = encode_encoded(frame.seq, &bytes[..n], frame.ack, &mut out).unwrap();
        prop_assert_eq!(&out[..m], &encode(&frame)[..]);
    }

    /// A ray packed from where a node keeps it, with a hop's changes beside
    /// it, is the wire form of the message it stands for, and
    /// that message is the ray with those changes made.
    #[test]
    fn an_outgoing_ray_is_the_message_it_stands_for(
        ray in arb_ray(),
        class in any::<u16>(),
        tag in any::<u16>(),
        origin_at_eye in any::<bool>(),
        granted in any::<bool>(),
    ) {
        let out = OutgoingRay { ray: &ray, class, tag, origin_at_eye, granted };
        let mut bytes = [0u8; MAX_MESSAGE_LEN];
        let n = encode_outgoing_ray(&out, &mut bytes).unwrap();
        let msg = out.message();
        prop_assert_eq!(&bytes[..n], &wire(&msg)[..]);
        let origin = if origin_at_eye { ray_wire::ORIGIN_AT_EYE } else { ray.origin };
        let sent = RayMsg { origin, class, tag, ..ray };
        prop_assert_eq!(msg, if granted { Message::GrantedRay(sent) } else { Message::Ray(sent) });
    }

    /// A channel decodes into one frame it keeps: a frame decoded replaces
    /// all of it (one without an acknowledgement clears the last one's), a
    /// damaged one leaves it as it was.
    #[test]
    fn decoding_into_a_kept_frame_replaces_it_or_leaves_it(
        kept in arb_frame(),
        next in arb_frame(),
        ray in arb_ray(),
        at in any::<prop::sample::Index>(),
    ) {
        let ray_frame = Frame { msg: Message::GrantedRay(ray), ..next.clone() };
        for next in [next, ray_frame] {
            let bytes = encode(&next);
            let mut out = kept.clone();
            let mut dec = FrameDecoder::new();
            prop_assert_eq!(dec.decode_into(&mut &bytes[..], &mut out), Some(Ok(())));
            prop_assert_eq!(&out, &next);

            // One byte before the delimiter changed, never to a zero.
            let mut damaged = bytes.clone();
            let i = at.index(damaged.len() - 1);
            damaged[i] = if damaged[i] == 0xff { 0xfe } else { damaged[i] + 1 };
            let mut out = kept.clone();
            let mut rest = &damaged[..];
            while let Some(result) = dec.decode_into(&mut rest, &mut out) {
                prop_assert!(result.is_err(), "a damaged frame decoded");
            }
            prop_assert_eq!(&out, &kept);
        }
    }

    /// Every frame's payload is its body (postcard's serialization, but for
    /// a ray's message: see `wire`), the trailer and the CRC, whichever path
    /// wrote it (rays are packed without serde), and such a payload decodes
    /// to the frame. A ray's message as postcard writes it, its variant's
    /// index before the ray, is a second encoding and is refused.
    #[test]
    fn a_frame_is_postcard_under_the_crc(frame in arb_frame(), ray in arb_ray(), granted in any::<bool>()) {
        let msg = if granted { Message::GrantedRay(ray) } else { Message::Ray(ray) };
        let as_postcard = postcard::to_slice(&(5u8, &msg), &mut [0u8; 256]).unwrap().to_vec();
        prop_assert_eq!(
            decode_all(&mut FrameDecoder::new(), &payload_frame(&as_postcard, &[])),
            vec![Err(DecodeError::Body)]
        );
        let batch = [vec![5u8, 0x7F, 2], wire(&Message::Space), as_postcard[1..].to_vec()].concat();
        let mut dec = FrameDecoder::new();
        prop_assert_eq!(decode_all(&mut dec, &payload_frame(&batch, &[])), vec![Ok(Frame::new(5, Message::Space)), Err(DecodeError::Body)]);
        let ray_frame = Frame { msg: if granted { Message::GrantedRay(ray) } else { Message::Ray(ray) }, ..frame.clone() };
        for frame in [frame, ray_frame] {
            let body = body_of(frame.seq, &frame.msg);
            let trailer: Vec<u8> = frame.ack.into_iter().collect();
            let reference = payload_frame(&body, &trailer);
            prop_assert_eq!(encode(&frame), reference.clone());
            prop_assert_eq!(decode_all(&mut FrameDecoder::new(), &reference), vec![Ok(frame)]);
        }
    }

    /// Bytes after a ray's wire form that are not one acknowledgement, and a
    /// ray cut short, are refused.
    #[test]
    fn a_ray_body_with_bytes_out_of_place_is_refused(ray in arb_ray(), cut in 1usize..8, extra in 2usize..4) {
        let body = body_of(3, &Message::GrantedRay(ray));
        let short = &body[..body.len() - cut.min(body.len() - 3)];
        prop_assert_eq!(decode_all(&mut FrameDecoder::new(), &payload_frame(short, &[])), vec![Err(DecodeError::Body)]);
        let long = vec![1u8; extra];
        prop_assert_eq!(decode_all(&mut FrameDecoder::new(), &payload_frame(&body, &long)), vec![Err(DecodeError::Body)]);
    }

    /// Any change to any single byte (other than the delimiters) is detected, and
    /// the decoder then reads the next frame intact.
    #[test]
    fn corrupted_byte_is_detected_at_every_position(frame in arb_frame(), flip in 1u8..=255, salt in any::<u8>()) {
        let clean = encode(&frame);
        for pos in 1..clean.len() - 1 {
            let mut bytes = clean.clone();
            // Replace with a different value; a zero splits the frame in two.
            bytes[pos] ^= flip.wrapping_add(salt).max(1);
            bytes.extend_from_slice(&clean);
            let mut dec = FrameDecoder::new();
            let got = decode_all(&mut dec, &bytes);
            prop_assert!(got.len() >= 2, "pos {}: {:?}", pos, got);
            prop_assert_eq!(got.last().unwrap(), &Ok(frame.clone()));
            for r in &got[..got.len() - 1] {
                prop_assert!(r.is_err(), "pos {}: corrupted frame accepted: {:?}", pos, r);
            }
        }
    }

    /// Arbitrary bytes never panic the decoder, and a good frame after them is read.
    #[test]
    fn garbage_then_resync(
        garbage in proptest::collection::vec(any::<u8>(), 0..600),
        a in arb_frame(),
        b in arb_frame(),
    ) {
        let mut dec = FrameDecoder::new();
        let _ = decode_all(&mut dec, &garbage);
        // Garbage with no delimiter after it runs into the next frame, and
        // the CRC refuses the two together; the frame after decodes.
        let got = decode_all(&mut dec, &encode(&a));
        if garbage.last().is_none_or(|&b| b == 0) {
            prop_assert_eq!(got.last(), Some(&Ok(a)));
        }
        let got = decode_all(&mut dec, &encode(&b));
        prop_assert_eq!(got, vec![Ok(b)]);
    }

    /// A frame cut short damages itself and the frame it runs into, no more.
    #[test]
    fn truncated_frame_then_resync(a in arb_frame(), b in arb_frame(), c in arb_frame(), cut in 0.0f64..1.0) {
        let first = encode(&a);
        let keep = ((first.len() - 1) as f64 * cut) as usize;
        let mut bytes = first[..keep].to_vec();
        bytes.extend_from_slice(&encode(&b));
        let mut dec = FrameDecoder::new();
        let got = decode_all(&mut dec, &bytes);
        prop_assert!(got.iter().all(|r| r.is_err()) || keep == 0, "a cut frame decoded: {:?}", got);
        prop_assert_eq!(decode_all(&mut dec, &encode(&c)), vec![Ok(c)]);
    }
}

/// Streams of frames, garbage, cut frames and over-long runs, in any order.
fn arb_stream() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        arb_frame().prop_map(|f| encode(&f)),
        proptest::collection::vec(any::<u8>(), 0..40),
        proptest::collection::vec(1u8..=255, MAX_FRAME_LEN - 2..MAX_FRAME_LEN + 3),
        (arb_frame(), any::<prop::sample::Index>()).prop_map(|(f, cut)| {
            let bytes = encode(&f);
            bytes[..cut.index(bytes.len())].to_vec()
        }),
    ];
    proptest::collection::vec(piece, 0..8).prop_map(|pieces| pieces.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Runs fed to `decode`, however they are cut (single bytes included),
    /// give one result per delimited segment: `Oversize` for one longer than
    /// the buffer (even unterminated), else the frame it holds, as decoded
    /// whole.
    #[test]
    fn decoding_runs_gives_one_result_per_segment(
        stream in arb_stream(),
        cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..6),
        bytewise in any::<bool>(),
    ) {
        let segments: Vec<&[u8]> = stream.split(|&b| b == 0).collect();
        let last = segments.len() - 1;
        let mut expected = Vec::new();
        for (i, seg) in segments.iter().enumerate() {
            if seg.len() > MAX_FRAME_LEN {
                expected.push(Err(DecodeError::Oversize));
            } else if i < last && !seg.is_empty() {
                let whole = [*seg, &[0][..]].concat();
                let mut run = &whole[..];
                expected.push(FrameDecoder::new().decode(&mut run).unwrap());
            }
        }
        let mut at: Vec<usize> = if bytewise {
            (0..=stream.len()).collect()
        } else {
            cuts.iter().map(|c| c.index(stream.len() + 1)).chain([0, stream.len()]).collect()
        };
        at.sort_unstable();
        let mut dec = FrameDecoder::new();
        let mut got = Vec::new();
        for pair in at.windows(2) {
            let mut run = &stream[pair[0]..pair[1]];
            while let Some(result) = dec.decode(&mut run) {
                got.push(result);
            }
            prop_assert!(run.is_empty());
        }
        prop_assert_eq!(got, expected);
    }
}

#[test]
fn oversize_is_reported_once_then_resyncs() {
    let mut dec = FrameDecoder::new();
    let junk = vec![0x55u8; MAX_FRAME_LEN * 3];
    assert_eq!(decode_all(&mut dec, &junk), vec![Err(DecodeError::Oversize)]);
    // The frame the junk runs into goes with it; the next decodes.
    let (lost, frame) = (Frame::new(1, Message::Ack(9)), Frame::new(2, Message::Ack(9)));
    assert_eq!(decode_all(&mut dec, &encode(&lost)), vec![]);
    assert_eq!(decode_all(&mut dec, &encode(&frame)), vec![Ok(frame)]);
}

#[test]
fn short_output_buffer_is_an_error() {
    let mut out = [0u8; 3];
    let frame = Frame::new(1, Message::Nak(2));
    assert_eq!(encode_frame(&frame, &mut out), Err(EncodeError::BufferTooSmall));
}

#[test]
fn largest_message_fits_the_frame_buffer() {
    // A ray with every field at its widest varint encoding.
    let ray = RayMsg {
        origin: [i32::MIN; 3],
        dir: [i32::MIN; 3],
        cell: [u16::MAX; 3],
        pixel: u32::MAX,
        weight: [u32::MAX; 3],
        credit: u64::MAX,
        kind: RayKind::Shadow,
        depth: u8::MAX,
        ignore: Some(u16::MAX),
        best: Some(HitMsg {
            t: i32::MIN,
            sphere: SphereMsg {
                id: u16::MAX,
                center: [i32::MIN; 3],
                radius: i32::MIN,
                material: MaterialMsg {
                    color: [u16::MAX; 3],
                    ambient: u16::MAX,
                    diffuse: u16::MAX,
                    specular: u16::MAX,
                    shininess: u8::MAX,
                    reflect: u16::MAX,
                },
            },
        }),
        t_max: Some(i32::MIN),
        class: u16::MAX,
        tag: u16::MAX,
    };
    let frame = Frame { seq: Seq::MAX, msg: Message::Ray(ray), ack: Some(Seq::MAX) };
    let bytes = encode(&frame);
    assert!(bytes.len() <= MAX_FRAME_LEN);
    println!("largest ray frame {} bytes, MAX_FRAME_LEN {}", bytes.len(), MAX_FRAME_LEN);
}

#[test]
fn a_sequence_number_and_an_acknowledgement_take_a_byte_each_whatever_their_value() {
    // postcard's varint took two bytes for a `u16` from 128 on, three from
    // 16 384: every frame of a long stream carried up to four bytes more.
    let ray = Message::GrantedRay(RayMsg {
        origin: [5 << 16, 7 << 16, -(3 << 16)],
        dir: [1 << 29, 0, 0],
        cell: [3, 4, 5],
        pixel: 4242,
        weight: [32768; 3],
        credit: 1 << 32,
        kind: RayKind::Reflected,
        depth: 1,
        ignore: Some(17),
        best: None,
        t_max: None,
        class: 2,
        tag: 0,
    });
    let small = encode(&Frame { seq: 0, msg: ray.clone(), ack: Some(0) }).len();
    for seq in [127, 128, 200, Seq::MAX] {
        assert_eq!(encode(&Frame { seq, msg: ray.clone(), ack: Some(seq) }).len(), small, "seq {seq}");
    }
    let bare = encode(&Frame::new(Seq::MAX, ray)).len();
    assert_eq!(small, bare + 1, "the acknowledgement trailer is one byte");
}

/// `msgs` numbered from `seq`, as a channel's window holds them.
fn numbered(seq: Seq, msgs: &[Message]) -> Vec<(Seq, &Message)> {
    msgs.iter().enumerate().map(|(i, m)| (seq.wrapping_add(i as u8), m)).collect()
}

/// A message's wire form: as postcard writes it, but for a ray's, which is
/// the ray's bare bytes as postcard writes them (with no variant index
/// before them: the ray's head byte is the tag) and [`ray_wire::GRANTED`]
/// set in that byte on a grant.
fn wire(msg: &Message) -> Vec<u8> {
    let bare = |ray: &RayMsg| postcard::to_slice(ray, &mut [0u8; 512]).unwrap().to_vec();
    match msg {
        Message::Ray(ray) => bare(ray),
        Message::GrantedRay(ray) => {
            let mut bytes = bare(ray);
            bytes[0] |= ray_wire::GRANTED;
            bytes
        }
        _ => postcard::to_slice(msg, &mut [0u8; 512]).unwrap().to_vec(),
    }
}

/// A frame's body: its sequence number, then its message's wire form.
fn body_of(seq: Seq, msg: &Message) -> Vec<u8> {
    let mut body = vec![seq];
    body.extend(wire(msg));
    body
}

/// `msgs` numbered from `seq` in their wire form, as a sender's window keeps them.
fn encoded(seq: Seq, msgs: &[Message]) -> Vec<(Seq, Vec<u8>)> {
    numbered(seq, msgs).into_iter().map(|(seq, m)| (seq, wire(m))).collect()
}

/// What `encode_batch` takes of `encoded`.
fn borrowed(encoded: &[(Seq, Vec<u8>)]) -> impl Iterator<Item = (Seq, &[u8])> {
    encoded.iter().map(|(seq, bytes)| (*seq, bytes.as_slice()))
}

/// The frames a batch of `msgs` from `seq` should decode to.
fn batch_frames(seq: Seq, msgs: &[Message], ack: Option<Seq>) -> Vec<Result<Frame, DecodeError>> {
    numbered(seq, msgs)
        .into_iter()
        .enumerate()
        .map(|(i, (seq, msg))| Ok(Frame { seq, msg: msg.clone(), ack: if i == 0 { ack } else { None } }))
        .collect()
}

fn wire_len(msg: &Message) -> usize {
    wire(msg).len()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// A batch is `seq ++ [0x7F, count | 0x80 if acked] ++ [ack] ++` the
    /// messages as postcard writes them, under the CRC; it takes as many
    /// messages as fit in a frame, at least one, and decodes to each in
    /// turn, numbered on from `seq`, the acknowledgement on the first.
    #[test]
    fn a_batch_is_its_messages_one_after_another(
        seq in any::<Seq>(),
        msgs in proptest::collection::vec(arb_message(), 1..10),
        rays in proptest::collection::vec(arb_ray(), 0..6),
        ack in any::<Option<Seq>>(),
    ) {
        let msgs: Vec<Message> = msgs.into_iter().chain(rays.into_iter().map(Message::GrantedRay)).collect();
        let mut out = [0u8; MAX_FRAME_LEN];
        let (n, taken) = encode_batch(borrowed(&encoded(seq, &msgs)), ack, &mut out).unwrap();
        let head = 3 + usize::from(ack.is_some());
        let sizes: Vec<usize> = msgs.iter().map(wire_len).collect();
        let used: usize = head + sizes[..taken].iter().sum::<usize>() + 4;
        prop_assert!(taken >= 1 && (taken == 1 || used <= MAX_PAYLOAD_LEN));
        if let Some(next) = sizes.get(taken) {
            prop_assert!(taken == 127 || used + next > MAX_PAYLOAD_LEN, "room for another");
        }
        if taken == 1 {
            // Alone, a message goes in a frame of its own.
            prop_assert_eq!(&out[..n], &encode(&Frame { seq, msg: msgs[0].clone(), ack })[..]);
        } else {
            let mut body = vec![seq, 0x7F, taken as u8 | if ack.is_some() { 0x80 } else { 0 }];
            body.extend(ack);
            for m in &msgs[..taken] {
                body.extend_from_slice(&wire(m));
            }
            prop_assert_eq!(&out[..n], &payload_frame(&body, &[])[..]);
        }
        prop_assert_eq!(decode_all(&mut FrameDecoder::new(), &out[..n]), batch_frames(seq, &msgs[..taken], ack));
    }

    /// A batch with any byte damaged hands out none of its messages, and
    /// the frame after it decodes intact.
    #[test]
    fn a_damaged_batch_gives_no_message(
        msgs in proptest::collection::vec(arb_message(), 2..5),
        flip in 1u8..=255,
        at in any::<prop::sample::Index>(),
        next in arb_frame(),
    ) {
        let mut out = [0u8; MAX_FRAME_LEN];
        let (n, _) = encode_batch(borrowed(&encoded(200, &msgs)), Some(3), &mut out).unwrap();
        let mut bytes = out[..n].to_vec();
        let i = 1 + at.index(n - 2);
        bytes[i] ^= flip;
        bytes.extend(encode(&next));
        let got = decode_all(&mut FrameDecoder::new(), &bytes);
        prop_assert_eq!(got.last(), Some(&Ok(next)));
        prop_assert!(got[..got.len() - 1].iter().all(Result::is_err), "{:?}", got);
    }
}

#[test]
fn a_batch_ends_at_a_gap_in_sequence_numbers() {
    let msgs = [Message::Space, Message::Grant(3), Message::Space];
    let frames = [(4, wire(&msgs[0])), (5, wire(&msgs[1])), (7, wire(&msgs[2]))];
    let mut out = [0u8; MAX_FRAME_LEN];
    let (n, taken) = encode_batch(borrowed(&frames), None, &mut out).unwrap();
    assert_eq!(taken, 2);
    assert_eq!(decode_all(&mut FrameDecoder::new(), &out[..n]), batch_frames(4, &msgs[..2], None));
    // Nothing to send is an error, not an empty frame.
    assert_eq!(encode_batch([], None, &mut out), Err(EncodeError::BufferTooSmall));
}

#[test]
fn a_batch_whose_count_disagrees_with_its_messages_is_refused() {
    let space = postcard::to_slice(&Message::Space, &mut [0u8; 4]).unwrap().to_vec();
    let batch = |count: u8, messages: usize| {
        let mut body = vec![9, 0x7F, count];
        (0..messages).for_each(|_| body.extend_from_slice(&space));
        decode_all(&mut FrameDecoder::new(), &payload_frame(&body, &[]))
    };
    let first = Ok(Frame::new(9, Message::Space));
    // One message short: those there are handed out, then the gap refused.
    assert_eq!(batch(3, 2), vec![first.clone(), Ok(Frame::new(10, Message::Space)), Err(DecodeError::Body)]);
    // Bytes after the last message, and an empty batch.
    assert_eq!(batch(1, 2), vec![Err(DecodeError::Body)]);
    assert_eq!(batch(0, 1), vec![Err(DecodeError::Body)]);
    // An acknowledgement flagged but missing.
    assert_eq!(
        decode_all(&mut FrameDecoder::new(), &payload_frame(&[9, 0x7F, 0x81], &[])),
        vec![Err(DecodeError::Body)]
    );
}

/// A frame built by hand: `body ++ trailer ++ crc`, each byte `i` of that
/// XORed with byte `i % 4` of the protocol's mask (little-endian), stuffed
/// by the `cobs` crate's rules and delimited.
fn payload_frame(body: &[u8], trailer: &[u8]) -> Vec<u8> {
    let mut payload = [body, trailer].concat();
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    let mask = link_proto::frame::MASK.to_le_bytes();
    for (i, b) in payload.iter_mut().enumerate() {
        *b ^= mask[i % 4];
    }
    let mut out = Vec::new();
    let mut cobs = vec![0u8; payload.len() + payload.len() / 254 + 2];
    let n = link_proto::cobs::encode(&payload, &mut cobs).unwrap();
    out.extend_from_slice(&cobs[..n]);
    out.push(0);
    out
}

#[test]
fn a_frame_without_a_trailer_decodes_as_before_the_trailer_existed() {
    // The body alone, as a peer that predates the acknowledgement trailer writes it.
    let mut buf = [0u8; 8];
    let body = postcard::to_slice(&(7u8, Message::Space), &mut buf).unwrap().to_vec();
    let mut dec = FrameDecoder::new();
    let got = decode_all(&mut dec, &payload_frame(&body, &[]));
    assert_eq!(got, vec![Ok(Frame::new(7, Message::Space))]);
    // The same with a trailer: one byte, whatever its value.
    let got = decode_all(&mut dec, &payload_frame(&body, &[0xac]));
    assert_eq!(got, vec![Ok(Frame { seq: 7, msg: Message::Space, ack: Some(0xac) })]);
}

#[test]
fn a_trailer_that_is_not_exactly_one_acknowledgement_is_refused() {
    let mut buf = [0u8; 8];
    let body = postcard::to_slice(&(7u8, Message::Space), &mut buf).unwrap().to_vec();
    let mut dec = FrameDecoder::new();
    // One byte too many, and a `u16` varint as the trailer was before `Seq`.
    for trailer in [&[0x01u8, 0x02][..], &[0xac, 0x02], &[0xff, 0xff, 0x03]] {
        let got = decode_all(&mut dec, &payload_frame(&body, trailer));
        assert_eq!(got, vec![Err(DecodeError::Body)], "trailer {trailer:02x?}");
    }
}

#[test]
fn sliding_staggers_the_rows_of_any_start_and_keeps_staggered_columns() {
    use Boundaries::*;
    let cases = [
        (Whole, Whole, StaggeredRows),
        (StaggeredRows, StaggeredRows, StaggeredRows),
        (StaggeredColumns, StaggeredColumns, StaggeredColumns),
    ];
    for (start, still, sliding) in cases {
        assert_eq!(start.when_sliding(false), still, "{start:?}");
        assert_eq!(start.when_sliding(true), sliding, "{start:?}");
    }
}

#[test]
fn a_batch_message_put_back_comes_again_before_any_byte() {
    let msgs = [Message::Grant(1), Message::Space, Message::Grant(3)];
    let mut out = [0u8; MAX_FRAME_LEN];
    let (n, _) = encode_batch(borrowed(&encoded(10, &msgs)), Some(4), &mut out).unwrap();
    let mut dec = FrameDecoder::new();
    let mut bytes = &out[..n];
    let first = dec.decode(&mut bytes).unwrap().unwrap();
    assert_eq!(first, Frame { seq: 10, msg: Message::Grant(1), ack: Some(4) });
    // The first, put back, comes again (its acknowledgement taken already).
    assert!(dec.unread() && dec.holds_batch());
    let mut next = Vec::new();
    let mut more = &[0x55u8][..];
    next.push(dec.decode(&mut more).unwrap().unwrap());
    assert_eq!(more, &[0x55], "no byte read while the batch is held");
    next.push(dec.decode(&mut bytes).unwrap().unwrap());
    assert!(dec.unread(), "the second put back");
    next.extend(std::iter::from_fn(|| dec.decode(&mut bytes)).map(Result::unwrap));
    let seqs: Vec<_> = next.iter().map(|f| (f.seq, f.msg.clone(), f.ack)).collect();
    assert_eq!(
        seqs,
        [
            (10, msgs[0].clone(), None),
            (11, msgs[1].clone(), None),
            (11, msgs[1].clone(), None),
            (12, msgs[2].clone(), None)
        ]
    );
    // The last too, while no byte has come after it.
    assert!(!dec.holds_batch() && dec.unread());
    assert_eq!(dec.decode(&mut bytes), Some(Ok(Frame::new(12, msgs[2].clone()))));
    assert_eq!(dec.decode(&mut bytes), None);
    // A frame of its own cannot be put back.
    let mut dec = FrameDecoder::new();
    let single = encode(&Frame::new(1, Message::Space));
    assert!(dec.decode(&mut &single[..]).unwrap().is_ok());
    assert!(!dec.unread());
}

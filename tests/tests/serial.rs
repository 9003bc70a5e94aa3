//! The serial backend's errors: a missing device, and (over a
//! pseudo-terminal) a node speaking another protocol version. A busy device
//! (EBUSY) cannot be staged here: the tests run as root, which may open an
//! exclusive tty anyway.

use std::io::Write;
use std::time::Duration;

use host_tool::plan::options::RenderOptions;
use host_tool::scene::Scene;
use host_tool::session::backend::render_serial;
use link_proto::{BoardInfo, Capacity, Frame, Hello, MAX_FRAME_LEN, Message, encode_frame};
use serialport::{SerialPort, TTYPort};

fn scene() -> Scene {
    Scene::random(4, 1, 1.0, [4, 4, 4]).expect("valid scene")
}

#[test]
fn a_missing_device_is_a_serial_error() {
    let opts = RenderOptions::new([1, 1, 1]);
    let err = render_serial(&scene(), &opts, &["/dev/no-such-board".into()], false, Duration::from_secs(1))
        .expect_err("no device, no render");
    assert_eq!(err.exit_code(), 21, "{err}");
    assert!(err.to_string().contains("/dev/no-such-board") && err.to_string().contains("missing"), "{err}");
}

#[test]
fn a_node_of_another_protocol_version_is_refused() {
    let (mut master, slave) = TTYPort::pair().expect("a pty pair");
    let path = slave.name().expect("pty has a name");
    // The slave stays open until the host has its own: with no slave open,
    // a write to the master can fail, the fake node would stop and drop the
    // master, and the device would vanish before the host opens it.
    // A node from the future: it says hello with version 99, over and over,
    // until the host is done (the pty lasts as long as this end is open).
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop = done.clone();
    let node = std::thread::spawn(move || {
        let hello = Message::Hello(Hello {
            version: 99,
            node: 0,
            capacity: Capacity { spheres: 8, refs: 64, cubes: 64, rays: 64 },
            board: BoardInfo::HOST,
            session: 0,
        });
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode_frame(&Frame::new(0, hello), &mut buf).expect("encodes");
        for _ in 0..1500 {
            if stop.load(std::sync::atomic::Ordering::Relaxed) || master.write_all(&buf[..n]).is_err() {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    let opts = RenderOptions::new([1, 1, 1]);
    let err = render_serial(&scene(), &opts, &[path], false, Duration::from_secs(5)).expect_err("refused");
    drop(slave);
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    assert_eq!(err.exit_code(), 31, "{err}");
    assert!(err.to_string().contains("version 99"), "{err}");
    node.join().expect("fake node");
}

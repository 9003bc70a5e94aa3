//! A reliable link over a lossy byte stream: go-back-N with cumulative acks.
//!
//! Serial links between boards lose and corrupt bytes; a lost ray is a wrong
//! pixel. Each data frame carries a sequence number (the frame's CRC catches
//! corruption, so a damaged frame is simply lost). The receiver takes frames
//! in order only and acknowledges the last one it took, cumulatively; a frame
//! out of order makes it send a negative acknowledgement for the one it
//! expects. The sender keeps up to `W` unacknowledged frames and sends them
//! all again from the oldest on a negative acknowledgement or when no
//! acknowledgement has come for `timeout` ticks, waiting twice as long after
//! each time-out in a row ([`MAX_BACKOFF`]). Sans-IO: the caller passes
//! the time in; storage is fixed at compile time.
//!
//! **Synchronisation.** Before its first data frame a channel sends
//! [`Message::Sync`] with its *incarnation* (a number its owner picks anew on
//! every start) until the peer answers [`Message::SyncAck`]; a receiver takes
//! data only from a peer whose `Sync` it has seen. A `Sync` with a new
//! incarnation from a peer already known means the peer restarted: the channel
//! counts it, starts both directions again from sequence number 0 (its
//! unacknowledged frames go to the new incarnation), and lets its owner know
//! ([`Channel::take_peer_restart`]). A duplicate or late `Sync` of the known
//! incarnation is only answered again, so it can never reset a running stream.
//! One exception to "no data before `Sync`": a hello of another protocol
//! version, so that a peer that predates `Sync` is still told apart.

use link_proto::{
    DecodeError, EncodeError, Frame, FrameDecoder, MAX_FRAME_LEN, Message, OutgoingRay, PROTOCOL_VERSION,
    Seq, encode_batch, encode_encoded, encode_parts,
};

use crate::window::Window;

/// Unacknowledged frames a channel keeps on every link of the array, the
/// host's included. Both ends must keep the same: a receiver acknowledges
/// alone once it has taken half a window, counting on the sender to have
/// the other half to send meanwhile. Sixteen against eight halves the
/// frames of acknowledgements alone on a one-way stream of rays (a granted
/// hop end 1 036 -> 1 013 instructions, a reply's 512 -> 489) for 7.5 KiB
/// more RAM on a board (seven channels of eight more slots).
pub const WINDOW: usize = 16;

/// Sequence numbers wrap at 2^8; a window is far smaller (see
/// [`Channel::new`]), so `a` precedes `b` when the forward distance from `a`
/// to `b` is less than half the space.
fn precedes(a: Seq, b: Seq) -> bool {
    a != b && b.wrapping_sub(a) < 0x80
}

/// Doublings of the resend time-out after time-outs in a row (16 times the
/// time-out at most), as TCP backs off its retransmission timer.
pub const MAX_BACKOFF: u32 = 4;

/// Counters of one channel (or, summed, of many).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ChannelStats {
    /// Data frames sent again.
    pub retransmitted: u32,
    /// Frames that failed their CRC or decoding.
    pub corrupted: u32,
    /// Data frames dropped as duplicates, out of order, or before a `Sync`.
    pub discarded: u32,
    /// Times the peer started again with a new incarnation.
    pub peer_restarts: u32,
}

impl core::ops::Add for ChannelStats {
    type Output = Self;

    fn add(self, o: Self) -> Self {
        Self {
            retransmitted: self.retransmitted + o.retransmitted,
            corrupted: self.corrupted + o.corrupted,
            discarded: self.discarded + o.discarded,
            peer_restarts: self.peer_restarts + o.peer_restarts,
        }
    }
}

impl core::ops::Sub for ChannelStats {
    type Output = Self;

    /// What happened between two readings, `self` the later.
    fn sub(self, o: Self) -> Self {
        Self {
            retransmitted: self.retransmitted.saturating_sub(o.retransmitted),
            corrupted: self.corrupted.saturating_sub(o.corrupted),
            discarded: self.discarded.saturating_sub(o.discarded),
            peer_restarts: self.peer_restarts.saturating_sub(o.peer_restarts),
        }
    }
}

impl core::iter::Sum for ChannelStats {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::default(), |a, b| a + b)
    }
}

/// One direction-pair of a reliable link: sends our data, receives theirs.
#[derive(Debug)]
pub struct Channel<const W: usize> {
    /// Unacknowledged data messages, oldest first, in their wire form.
    unacked: Window<W>,
    /// Sequence number of the next new data frame.
    next_seq: Seq,
    /// Index in `unacked` of the next frame to write.
    resend_from: usize,
    /// Frames at the front of `unacked` written at least once.
    written: usize,
    /// Last time the window made progress (an ack, or a send from its start).
    progress_at: u64,
    /// Sequence number expected next from the peer.
    expected: Seq,
    /// An ack or nak to send (control frames are not sequenced).
    control_due: Owed,
    /// An ack moved the window since the last transmit.
    acked_now: bool,
    /// Data frames taken since our last acknowledgement went out.
    taken_unacked: usize,
    /// Since when an acknowledgement has waited for a data frame to ride on
    /// (the time of the transmit before the frame it answers arrived).
    ack_held_since: Option<u64>,
    /// The time of the last transmit: receiving takes no clock.
    last_transmit: u64,
    /// The pending acknowledgement answers a duplicate: it goes at once.
    ack_urgent: bool,
    /// Since when the peer has owed an ack: the last ack that moved the
    /// window, or the first send into an empty window.
    owed_since: Option<u64>,
    /// Our incarnation, announced in `Sync`.
    incarnation: u32,
    /// The peer acknowledged our `Sync`: data frames may go.
    synced: bool,
    /// When our last `Sync` went out.
    sync_sent_at: Option<u64>,
    /// The peer's incarnation, once its `Sync` arrived.
    peer: Option<u32>,
    /// A `SyncAck` to send.
    sync_ack_due: Option<u32>,
    /// The peer restarted since the owner last asked.
    peer_restarted: bool,
    /// Data came from a peer we have no stream with: it still talks to our
    /// previous incarnation, and our `Sync` tells it we restarted.
    peer_unaware: bool,
    decoder: FrameDecoder,
    timeout: u64,
    /// How long the window may now go without progress before it is resent:
    /// `timeout`, doubled by each time-out in a row up to [`MAX_BACKOFF`]
    /// doublings, so that a link slower than the time-out assumes is not
    /// flooded with copies of what is still on its way.
    resend_wait: u64,
    /// Counters.
    pub stats: ChannelStats,
}

impl<const W: usize> Channel<W> {
    /// A channel of incarnation 0 that resends after `timeout` ticks without
    /// progress. Set the incarnation before the first transmit.
    pub const fn new(timeout: u64) -> Self {
        // Go-back-N tells new frames from old by sequence numbers only while
        // the window is under half their space.
        const { assert!(W < 0x80, "a window must be under half the sequence space") };
        Self {
            unacked: Window::new(),
            next_seq: 0,
            resend_from: 0,
            written: 0,
            progress_at: 0,
            expected: 0,
            control_due: Owed::Nothing,
            acked_now: false,
            taken_unacked: 0,
            ack_held_since: None,
            last_transmit: 0,
            ack_urgent: false,
            owed_since: None,
            incarnation: 0,
            synced: false,
            sync_sent_at: None,
            peer: None,
            sync_ack_due: None,
            peer_restarted: false,
            peer_unaware: false,
            decoder: FrameDecoder::new(),
            timeout,
            resend_wait: timeout,
            stats: ChannelStats { retransmitted: 0, corrupted: 0, discarded: 0, peer_restarts: 0 },
        }
    }

    /// Sets the incarnation announced to the peer: it must differ from the
    /// one this endpoint used before its last restart, or the peer cannot
    /// tell that it restarted.
    pub fn set_incarnation(&mut self, incarnation: u32) {
        self.incarnation = incarnation;
    }

    /// Resends after `timeout` ticks without progress from now on (the
    /// back-off starts again from it).
    pub fn set_timeout(&mut self, timeout: u64) {
        self.timeout = timeout;
        self.resend_wait = timeout;
    }

    /// Whether a new data message would fit in the window.
    pub fn can_send(&self) -> bool {
        !self.unacked.is_full()
    }

    /// Queues a data message; hands it back when the window is full.
    // Handing it back is the point: see `Links::try_send`.
    #[allow(clippy::result_large_err)]
    pub fn send(&mut self, msg: Message) -> Result<(), Message> {
        // Encoded once, into its slot; a full window refuses it before
        // encoding (a message always fits a slot).
        match self.unacked.push(self.next_seq, &msg) {
            Ok(()) => {
                self.next_seq = self.next_seq.wrapping_add(1);
                Ok(())
            }
            Err(_) => Err(msg),
        }
    }

    /// Queues the message `ray` stands for, packed from where the ray lies;
    /// whether it fitted (the caller still holds the ray when not).
    pub fn send_ray(&mut self, ray: &OutgoingRay<'_>) -> bool {
        let queued = self.unacked.push_ray(self.next_seq, ray).is_ok();
        if queued {
            self.next_seq = self.next_seq.wrapping_add(1);
        }
        queued
    }

    /// Feeds received bytes; hands in-order data messages to `deliver`, which
    /// returns false when it cannot take one: that frame is then not
    /// acknowledged, and the sender sends it again later.
    pub fn receive(&mut self, bytes: &[u8], mut deliver: impl FnMut(Message) -> bool) {
        let mut rest = bytes;
        // The decoder is not called once every byte is read and no batch
        // waits: that call finds nothing, and cost a received frame a tenth
        // of its framing.
        let more = |rest: &[u8], decoder: &FrameDecoder| !rest.is_empty() || decoder.holds_batch();
        if !more(rest, &self.decoder) {
            return;
        }
        // Decoded in place: a frame is as large as a ray with its hit.
        let mut frame = Frame::new(0, Message::Space);
        while more(rest, &self.decoder) {
            let Some(result) = self.decoder.decode_into(&mut rest, &mut frame) else { break };
            match result {
                Err(
                    DecodeError::Oversize
                    | DecodeError::Cobs
                    | DecodeError::Short
                    | DecodeError::Crc
                    | DecodeError::Body,
                ) => self.stats.corrupted += 1,
                Ok(()) if self.take(&mut frame, &mut deliver) => {}
                // Refused for room: a batch's message waits in the decoder
                // with the rest of its batch (`holds_back`) when no byte
                // after it has come; otherwise it is sent again.
                Ok(()) if rest.is_empty() && self.decoder.unread() => return,
                Ok(()) => self.stats.discarded += 1,
            }
        }
    }

    /// Whether messages of a batch wait for the owner to take them, which a
    /// call of [`Channel::receive`] with no bytes hands out: feed no bytes
    /// until they have gone (they would be dropped with the batch).
    pub fn holds_back(&self) -> bool {
        self.decoder.holds_batch()
    }

    /// The peer's incarnation, once its `Sync` has arrived.
    pub fn peer_incarnation(&self) -> Option<u32> {
        self.peer
    }

    /// Whether the peer restarted since the last call (then forgets it).
    pub fn take_peer_restart(&mut self) -> bool {
        core::mem::take(&mut self.peer_restarted)
    }

    /// Takes a decoded frame; false only when `deliver` refused its message.
    fn take(&mut self, frame: &mut Frame, deliver: &mut impl FnMut(Message) -> bool) -> bool {
        // A piggybacked ack counts as a standalone one would, whatever the
        // frame it rides on.
        if let Some(seq) = frame.ack
            && self.synced
        {
            self.acknowledged(seq);
        }
        match frame.msg {
            Message::Sync(incarnation) => self.peer_synced(incarnation),
            Message::SyncAck(incarnation) => {
                // An answer to an older incarnation's `Sync` is stale.
                if incarnation == self.incarnation && !self.synced {
                    self.synced = true;
                    self.acked_now = true;
                }
            }
            // Acks of a stream we have not started (a stale peer's) mean nothing.
            Message::Ack(_) | Message::Nak(_) if !self.synced => {}
            Message::Ack(seq) => self.acknowledged(seq),
            Message::Nak(seq) => {
                // Everything before `seq` arrived; resend from `seq`.
                self.acknowledged(seq.wrapping_sub(1));
                self.resend_from = 0;
            }
            // A peer of another protocol version may not know `Sync`; its
            // hello is taken as it comes, so the version mismatch is reported.
            Message::Hello(h) if self.peer.is_none() && h.version != PROTOCOL_VERSION => {
                deliver(Message::Hello(h));
            }
            _ if self.peer.is_none() => {
                self.stats.discarded += 1;
                self.peer_unaware = true;
            }
            _ if frame.seq == self.expected => {
                if !deliver(core::mem::replace(&mut frame.msg, Message::Space)) {
                    return false;
                }
                self.expected = self.expected.wrapping_add(1);
                self.control_due = Owed::Ack(frame.seq);
                self.taken_unacked += 1;
                self.ack_held_since.get_or_insert(self.last_transmit);
            }
            _ => {
                self.stats.discarded += 1;
                // A duplicate re-acks the last taken frame; a gap asks for the
                // missing one. Either way the peer is resending: answer now.
                self.ack_urgent = true;
                self.control_due = if precedes(frame.seq, self.expected) {
                    Owed::Ack(self.expected.wrapping_sub(1))
                } else {
                    Owed::Nak(self.expected)
                };
            }
        }
        true
    }

    /// The peer's `Sync`: a first one starts its stream, the same again is
    /// answered again, a new incarnation restarts both directions.
    fn peer_synced(&mut self, incarnation: u32) {
        self.sync_ack_due = Some(incarnation);
        match self.peer {
            Some(known) if known == incarnation => return,
            Some(_) => self.restart_stream(),
            None => {}
        }
        self.peer = Some(incarnation);
        self.expected = 0;
        self.ack_settled();
    }

    /// The peer lost our stream with its old state: renumber what it has not
    /// acknowledged from 0 and announce ourselves to the new incarnation.
    fn restart_stream(&mut self) {
        self.peer_restarted = true;
        self.stats.peer_restarts += 1;
        self.next_seq = self.unacked.renumber(0);
        self.resend_from = 0;
        self.written = 0;
        self.synced = false;
        self.sync_sent_at = None;
    }

    /// Drops every frame up to and including `seq` from the window.
    fn acknowledged(&mut self, seq: Seq) {
        while let Some(front) = self.unacked.front_seq() {
            if !(front == seq || precedes(front, seq)) {
                break;
            }
            self.unacked.pop_front();
            self.resend_from = self.resend_from.saturating_sub(1);
            self.written = self.written.saturating_sub(1);
            self.acked_now = true;
        }
    }

    /// Writes what is due at `now` (sync and acks, new frames, resends after a
    /// time-out) through `write`, which returns false when the byte link is full.
    pub fn transmit(&mut self, now: u64, write: impl FnMut(&[u8]) -> bool) {
        self.transmit_via(now, &mut [0; MAX_FRAME_LEN], write);
    }

    /// [`Channel::transmit`] encoding into the caller's scratch buffer, so
    /// that a node polling seven channels clears none of them per poll.
    pub fn transmit_via(
        &mut self,
        now: u64,
        buf: &mut [u8; MAX_FRAME_LEN],
        mut write: impl FnMut(&[u8]) -> bool,
    ) {
        let buf = buf.as_mut_slice();
        self.last_transmit = now;
        if let Some(incarnation) = self.sync_ack_due
            && write_control(Message::SyncAck(incarnation), buf, &mut write)
        {
            self.sync_ack_due = None;
        }
        self.track_progress(now);
        if self.synced && !self.unacked.is_empty() && now.saturating_sub(self.progress_at) >= self.resend_wait
        {
            // No progress for a whole time-out: go back to the oldest frame,
            // and wait twice as long before doing so again.
            self.resend_from = 0;
            self.progress_at = now;
            self.resend_wait = self.resend_wait.saturating_mul(2).min(self.timeout << MAX_BACKOFF);
        }
        // An ack rides on the first data frame that goes out; only without
        // one does it take a frame of its own, and then only once it answers
        // half a window or has waited long enough (a nak goes at once).
        let data_due = self.synced && self.resend_from < self.unacked.len();
        let owed = self.control_due;
        if !(matches!(owed, Owed::Ack(_)) && (data_due || !self.ack_alone_due(now)))
            && let Some(control) = owed.message()
            && write_control(control, buf, &mut write)
        {
            self.ack_settled();
        }
        if !self.synced {
            self.announce(now, buf, &mut write);
            return;
        }
        while self.resend_from < self.unacked.len() {
            // Set afresh on every write: an ack from an earlier write may
            // belong to a peer incarnation that has since restarted.
            let ack = match self.control_due {
                Owed::Ack(seq) => Some(seq),
                Owed::Nothing | Owed::Nak(_) => None,
            };
            let Ok((n, sent)) = self.encode_due(ack, buf) else { break };
            if !write(buf.get(..n).unwrap_or_default()) {
                break;
            }
            if ack.is_some() {
                self.ack_settled();
            }
            let again = self.written.saturating_sub(self.resend_from).min(sent);
            self.stats.retransmitted += again as u32;
            self.resend_from += sent;
            self.written = self.written.max(self.resend_from);
        }
    }

    /// Encodes the frames due from `resend_from` into `buf`, `ack` riding on
    /// them: one alone as it is, several in a batch as many as fit. The
    /// bytes and the frames they hold.
    fn encode_due(&self, ack: Option<Seq>, buf: &mut [u8]) -> Result<(usize, usize), EncodeError> {
        if self.unacked.len() - self.resend_from > 1 {
            return encode_batch(self.unacked.iter_from(self.resend_from), ack, buf);
        }
        let (seq, message) = self.unacked.get(self.resend_from).ok_or(EncodeError::BufferTooSmall)?;
        Ok((encode_encoded(seq, message, ack, buf)?, 1))
    }

    /// Whether an acknowledgement with no data frame to ride on should go in
    /// a frame of its own at `now`.
    ///
    /// A peer passing a stream of rays on grants gets nothing back to carry
    /// its acks, and a frame per ack cost each end of a hop about a third of
    /// its instructions. Acks wait until they answer half a window (the peer
    /// keeps the other half to send on, so a stream never stalls for them),
    /// for a quarter of the resend time-out (so a short burst is answered
    /// long before the peer would resend it), or until the peer resends.
    fn ack_alone_due(&mut self, now: u64) -> bool {
        if self.ack_urgent || self.taken_unacked >= (W / 2).max(1) {
            return true;
        }
        let since = self.ack_held_since.unwrap_or(now);
        now.saturating_sub(since) >= self.timeout / 4
    }

    /// No acknowledgement is owed any more: it went out, alone or riding on
    /// a data frame, or the peer's stream started again.
    fn ack_settled(&mut self) {
        self.control_due = Owed::Nothing;
        self.taken_unacked = 0;
        self.ack_held_since = None;
        self.ack_urgent = false;
    }

    /// Notes when the window last moved and since when the peer owes an answer.
    fn track_progress(&mut self, now: u64) {
        let acked = core::mem::take(&mut self.acked_now);
        if acked || self.unacked.is_empty() {
            self.progress_at = now;
            self.resend_wait = self.timeout;
        }
        self.owed_since = match (self.unacked.is_empty(), self.owed_since) {
            (true, _) => None,
            (false, Some(since)) if !acked => Some(since),
            (false, _) => Some(now),
        };
    }

    /// Sends our `Sync` once there is data to start a stream for, and again
    /// after every time-out without an answer; or once to a peer that sent
    /// data without one, so that it learns we restarted.
    fn announce(&mut self, now: u64, buf: &mut [u8], write: &mut impl FnMut(&[u8]) -> bool) {
        let due = self.sync_sent_at.is_none_or(|at| now.saturating_sub(at) >= self.timeout);
        let wanted = !self.unacked.is_empty() || self.peer_unaware;
        if wanted && due && write_control(Message::Sync(self.incarnation), buf, write) {
            self.sync_sent_at = Some(now);
            self.peer_unaware = false;
        }
    }

    /// How long the peer has left data frames unacknowledged at `now` (zero
    /// when nothing is owed): a peer that stops answering shows here.
    pub fn unanswered_for(&self, now: u64) -> u64 {
        self.owed_since.map_or(0, |since| now.saturating_sub(since))
    }

    /// Whether data frames await acknowledgement or control frames are due.
    pub fn busy(&self) -> bool {
        !self.unacked.is_empty() || self.control_due != Owed::Nothing || self.sync_ack_due.is_some()
    }
}

/// What a channel owes its peer besides data: an acknowledgement, a nak, or
/// nothing. Its own small type rather than an `Option<Message>`: it is read
/// on every transmit, where a `Message` is a ray's size to copy, and
/// `Nothing` is zero bytes, so that a board's channels, built by a `const`
/// constructor, are all zero and take no flash for their initial values
/// (`FramedLinks::new`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Owed {
    Nothing = 0,
    Ack(Seq) = 1,
    Nak(Seq) = 2,
}

impl Owed {
    /// The control message that pays it, if anything is owed.
    fn message(self) -> Option<Message> {
        match self {
            Owed::Nothing => None,
            Owed::Ack(seq) => Some(Message::Ack(seq)),
            Owed::Nak(seq) => Some(Message::Nak(seq)),
        }
    }
}

/// Writes one unsequenced control frame; whether it went out whole.
fn write_control(msg: Message, buf: &mut [u8], write: &mut impl FnMut(&[u8]) -> bool) -> bool {
    encode_parts(0, &msg, None, buf).is_ok_and(|n| write(buf.get(..n).unwrap_or_default()))
}

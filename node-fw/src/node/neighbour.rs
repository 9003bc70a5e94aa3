//! What a node keeps about each of its six neighbour ports: whether the
//! array has a node there, the rays passed each way and their grants, and
//! the board at the other end of the cable.

use heapless::Deque;
use link_proto::{BoardId, RayReply};

use super::MAX_OUTSTANDING;

/// One neighbour port's state.
#[derive(Debug)]
pub(super) struct Neighbour {
    /// The array has a node there (from the assignment).
    pub(super) present: bool,
    /// Rays sent there without a reply yet.
    pub(super) outstanding: u8,
    /// Replies owed for rays that came from there.
    pub(super) replies: Deque<RayReply, MAX_OUTSTANDING>,
    /// A ray from there was refused since the last `Space`.
    pub(super) refused: bool,
    /// A `Space` is owed (a slot freed after a refusal).
    pub(super) space_due: bool,
    /// Rays the neighbour has granted us and we have not used.
    pub(super) grants_held: u16,
    /// Slots we set aside for the neighbour's rays.
    pub(super) grants_given: u16,
    /// Of those, the ones not yet told.
    pub(super) grants_due: u16,
    /// Frames the neighbour has said it ended (its `Finish` on this port).
    pub(super) ends_seen: u32,
    /// Our end of a frame is still to be told.
    pub(super) end_due: bool,
    /// The board that said hello there.
    pub(super) peer: Option<BoardId>,
    /// The host session its last hello named.
    pub(super) session: Option<u32>,
    /// Our hello is still to go.
    pub(super) hello_due: bool,
    /// The host is still to be told who is there.
    pub(super) note_due: bool,
}

impl Neighbour {
    /// A port nothing has happened on; our hello is due.
    pub(super) const NEW: Neighbour = Neighbour {
        present: false,
        outstanding: 0,
        replies: Deque::new(),
        refused: false,
        space_due: false,
        grants_held: 0,
        grants_given: 0,
        grants_due: 0,
        ends_seen: 0,
        end_due: false,
        peer: None,
        session: None,
        hello_due: true,
        note_due: false,
    };

    /// Forgets the rays and grants of a frame or a session; the cable and
    /// what was said on it stay.
    pub(super) fn forget_rays(&mut self) {
        self.outstanding = 0;
        self.replies.clear();
        self.refused = false;
        self.space_due = false;
        self.grants_held = 0;
        self.grants_given = 0;
        self.grants_due = 0;
    }

    /// Whether anything is owed on this port (or to the host about it).
    pub(super) fn owes(&self) -> bool {
        self.note_due || self.space_due || self.end_due || self.grants_due > 0 || !self.replies.is_empty()
    }

    /// Whether the grants held are of the frame this node is in: the
    /// neighbour has told us the end of every frame we ended. Until its end
    /// arrives, what we hold may be grants of the frame before, whose slots
    /// its new frame no longer sets aside.
    pub(super) fn grants_current(&self, ends: u32) -> bool {
        self.ends_seen == ends
    }
}

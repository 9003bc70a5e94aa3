//! Where in a node a failure was found: one name per check, so the host can
//! say which. An [`crate::ErrorReport`] of code `Unexpected` or `BadRay`
//! carries its site as `b`; an unexpected message carries `100 + ` its
//! [`MessageKind`] instead.

use crate::message::MessageKind;

/// A check that failed in a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Site {
    /// A control message found the node's control queue full.
    ControlQueueFull = 1,
    /// A slide message that no slide on its side expects.
    SlideMessage,
    /// A slab offered while a slide on that side is under way.
    OfferDuringSlide,
    /// A slab sphere without an offer.
    SlabSphereWithoutOffer,
    /// A slab's end without an offer.
    SlabEndWithoutOffer,
    /// A reply to a slide this node did not ask for.
    SlideReplyUnasked,
    /// A slide message from a port off the driving axis.
    SlideOffDrivingAxis,
    /// A ray passed on a grant this node did not give.
    GrantedRayWithoutGrant,
    /// A granted ray found its set-aside slot gone.
    GrantedRayWithoutSlot,
    /// More rays awaiting a reply than a neighbour may send.
    TooManyOutstandingRays,
    /// A reply to a ray this node did not send.
    ReplyToUnsentRay,
    /// An assignment outside the scene's loading.
    AssignOutOfPhase,
    /// An assignment to a place outside its array.
    AssignOutsideArray,
    /// A sphere outside the scene's loading.
    SphereOutOfPhase,
    /// A light outside the scene's loading.
    LightOutOfPhase,
    /// A scene's end outside its loading.
    SceneEndOutOfPhase,
    /// A frame's start before a scene is loaded.
    RenderStartOutOfPhase,
    /// A ray whose origin and direction make no line.
    RayWithoutLine,
    /// A ray whose cell is not on its line.
    RayCellOffLine,
    /// A best hit on a sphere the node does not hold.
    BestHitUnknown,
    /// A ray that leaves the subregion toward no neighbour.
    LeavesTowardNoNeighbour,
    /// A hit the node cannot shade.
    HitNotShadable,
    /// A ray to shade whose origin and direction make no line.
    ShadeWithoutLine,
    /// A ray to shade that misses its sphere.
    ShadeMissesSphere,
    /// A hit point with no surface there.
    ShadeWithoutSurface,
    /// A hit on a ray whose credit is too small to split among its
    /// children (a ray that was not split as the node splits).
    CreditTooSmall,
    /// A map of occupied cubes outside the scene's loading.
    OccupancyOutOfPhase,
    /// A scene that keeps a map of occupied cubes the node does not hold
    /// (none, or one of another grid).
    KeptMapNotHeld,
}

impl Site {
    /// Every site, in wire order.
    pub const ALL: [Site; 28] = [
        Site::ControlQueueFull,
        Site::SlideMessage,
        Site::OfferDuringSlide,
        Site::SlabSphereWithoutOffer,
        Site::SlabEndWithoutOffer,
        Site::SlideReplyUnasked,
        Site::SlideOffDrivingAxis,
        Site::GrantedRayWithoutGrant,
        Site::GrantedRayWithoutSlot,
        Site::TooManyOutstandingRays,
        Site::ReplyToUnsentRay,
        Site::AssignOutOfPhase,
        Site::AssignOutsideArray,
        Site::SphereOutOfPhase,
        Site::LightOutOfPhase,
        Site::SceneEndOutOfPhase,
        Site::RenderStartOutOfPhase,
        Site::RayWithoutLine,
        Site::RayCellOffLine,
        Site::BestHitUnknown,
        Site::LeavesTowardNoNeighbour,
        Site::HitNotShadable,
        Site::ShadeWithoutLine,
        Site::ShadeMissesSphere,
        Site::ShadeWithoutSurface,
        Site::CreditTooSmall,
        Site::OccupancyOutOfPhase,
        Site::KeptMapNotHeld,
    ];

    /// The site a report's `b` names.
    pub fn from_wire(b: u32) -> Option<Site> {
        Site::ALL.into_iter().find(|&s| s as u32 == b)
    }
}

/// What a report's `b` names: a site, or the kind of an unexpected message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Found {
    /// A check in the node.
    Site(Site),
    /// A message the node could not use in its state.
    Message(MessageKind),
}

impl From<Site> for Found {
    fn from(site: Site) -> Found {
        Found::Site(site)
    }
}

/// Offset of a message kind in a report's `b`.
pub const MESSAGE_BASE: u32 = 100;

impl Found {
    /// The report's `b`.
    pub fn to_wire(self) -> u32 {
        match self {
            Found::Site(s) => s as u32,
            Found::Message(k) => MESSAGE_BASE + k as u32,
        }
    }

    /// What a report's `b` names, if anything known.
    pub fn from_wire(b: u32) -> Option<Found> {
        match b.checked_sub(MESSAGE_BASE) {
            Some(k) => MessageKind::ALL.into_iter().find(|&m| m as u32 == k).map(Found::Message),
            None => Site::from_wire(b).map(Found::Site),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_site_and_kind_reads_back_from_its_number() {
        for s in Site::ALL {
            assert_eq!(Found::from_wire(Found::Site(s).to_wire()), Some(Found::Site(s)));
        }
        for k in MessageKind::ALL {
            assert_eq!(Found::from_wire(Found::Message(k).to_wire()), Some(Found::Message(k)));
        }
        assert_eq!(Found::from_wire(0), None);
        assert_eq!(Found::from_wire(99), None);
    }
}

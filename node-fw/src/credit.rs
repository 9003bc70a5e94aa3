//! Splitting a ray's credit at a hit, among the rays it spawns and itself.
//!
//! The host knows a frame is complete when it has back all the credit it
//! gave its pixels: every ray carries a share, a hit divides its ray's share
//! among its children and itself, and each ray's record returns what it kept
//! (Mattern's weights). A parent keeps some, so that its own record, which
//! may travel a slower host link than its children's, is waited for.
//!
//! The split is by powers of two, so that a share travels in one byte
//! ([`link_proto::credit`]): the reflection, the only child that can hit and
//! split again, takes half; each shadow ray takes `2^-m` of the other half,
//! for the least `m` with `2^m` above their number; the parent keeps the
//! rest, at least one such part. Down a chain of reflections a share halves
//! once a hit, so the smallest share of a pixel's 2^32 is 2^(32 - 8 - 1 - 4)
//! = 2^19, within [`link_proto::MAX_DEPTH`] reflections and eight lights.

/// The shares of one hit's children.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Split {
    /// Each shadow ray's share.
    pub shadow: u64,
    /// The reflection's share (zero when the hit spawns none).
    pub reflection: u64,
}

impl Split {
    /// The split of `credit` among `shadows` shadow rays, a reflection if
    /// there is one, and the parent; `None` when a share would be zero (the
    /// credit is too small to split: never within the documented limits).
    pub fn of(credit: u64, shadows: u8, reflection: bool) -> Option<Self> {
        let reflection = if reflection { (credit / 2).max(1) } else { 0 };
        let rest = credit.checked_sub(reflection)?;
        let m = (u32::from(shadows) + 1).next_power_of_two().trailing_zeros();
        let split = Self { shadow: rest >> m, reflection };
        let shares_given = u64::from(shadows) * split.shadow + split.reflection;
        let whole = (shadows == 0 || split.shadow > 0) && shares_given < credit;
        whole.then_some(split)
    }

    /// The share of a child: the reflection's or a shadow ray's.
    pub fn child(&self, reflected: bool) -> u64 {
        if reflected { self.reflection } else { self.shadow }
    }

    /// What the parent of `children` children keeps of `credit` (one of them
    /// the reflection when its share is not zero).
    pub fn own(&self, credit: u64, children: u8) -> u64 {
        let shadows = children.saturating_sub(u8::from(self.reflection > 0));
        credit.saturating_sub(u64::from(shadows) * self.shadow + self.reflection)
    }
}

#[cfg(test)]
mod tests {
    use super::Split;
    use link_proto::ray_wire::PIXEL_CREDIT;

    /// The shares add up to the credit exactly, each child's a power of two
    /// and not zero, the parent's not zero; checked over every count of
    /// lights and a chain of reflections to the deepest.
    #[test]
    fn shares_are_powers_of_two_that_add_up() {
        for lights in 0u8..=8 {
            let mut credit = PIXEL_CREDIT;
            for depth in 0..=9u32 {
                let reflection = depth < 9;
                let split = Split::of(credit, lights, reflection).expect("within the limits");
                let children = lights + u8::from(reflection);
                let own = split.own(credit, children);
                let given = u128::from(lights) * u128::from(split.shadow) + u128::from(split.reflection);
                assert_eq!(given + u128::from(own), u128::from(credit), "{lights} lights, depth {depth}");
                assert!(own > 0);
                if lights > 0 {
                    assert!(split.shadow.is_power_of_two(), "{split:?}");
                    // The least share of this hit, against the bound the module states.
                    assert!(split.shadow >= 1 << 19, "{lights} lights, depth {depth}: {split:?}");
                }
                if reflection {
                    assert!(split.reflection.is_power_of_two());
                    credit = split.reflection;
                }
            }
        }
    }

    #[test]
    fn a_credit_too_small_to_split_is_refused() {
        assert_eq!(Split::of(1, 1, true), None);
        assert_eq!(Split::of(2, 1, false), Some(Split { shadow: 1, reflection: 0 }));
        assert_eq!(Split::of(3, 3, false), None);
        assert_eq!(Split::of(0, 0, false), None);
    }
}

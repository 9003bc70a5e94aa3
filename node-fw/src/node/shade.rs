//! Shading a hit: the ambient term at once, the children (shadow rays,
//! reflection) spawned as the pool admits them, the parent retired with its
//! own share of the credit ([`crate::credit`]).

use link_proto::{ErrorCode, RayKind, RayMsg, Site};

use crate::credit::Split;
use crate::geometry::Line;
use crate::limits::Scalar;
use crate::pool::Stage;
use crate::shading::{Child, Surface};
use crate::sphere::Sphere;

use super::{Children, Node, Work, retire};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// The sphere of a ray's best hit, from the ray itself.
    fn hit_sphere(&self, ray: &RayMsg) -> Option<(Scalar, Sphere)> {
        let hit = ray.best?;
        let sphere = Sphere::from_msg(&hit.sphere, &self.grid).ok()?;
        Some((Scalar::from_bits(hit.t), sphere))
    }

    /// Evaluates the children of a hit into `spawned` (each with its candidate
    /// number), counts them to split the credit, and folds the ambient term
    /// and any child resolved at once into the parent's contribution.
    pub(super) fn begin_shading(
        &self,
        ray: &RayMsg,
        line: &Line,
        spawned: &mut Children,
    ) -> Result<Stage, Site> {
        let unshadable = Site::HitNotShadable;
        let (t, sphere) = self.hit_sphere(ray).ok_or(unshadable)?;
        let sphere = &sphere;
        let surface = Surface::at(line, t, sphere).ok_or(unshadable)?;
        let scene = self.scene();
        let mut rgb = scene.ambient(ray, sphere);
        for k in 0..scene.candidates() {
            match scene.child(ray, line, &surface, sphere, k) {
                Some(Child::Ray(child)) => spawned.push((k, child)).map_err(|_| unshadable)?,
                Some(Child::Done(c)) => rgb = add3(rgb, c),
                None => {}
            }
        }
        let children = spawned.len() as u8;
        if children == 0 {
            return Ok(Stage::Retire(retire(ray, rgb, ray.credit, 0)));
        }
        let reflected = spawned.iter().any(|(_, c)| c.kind == RayKind::Reflected);
        let shadows = children - u8::from(reflected);
        let split = Split::of(ray.credit, shadows, reflected).ok_or(Site::CreditTooSmall)?;
        Ok(Stage::Shade { next: 0, children, split, rgb })
    }

    /// Admits the children `begin_shading` evaluated while the pool has room,
    /// so a hit is evaluated once; only children the pool refuses now are
    /// evaluated again later, by [`Self::shade`].
    pub(super) fn spawn_evaluated(
        &mut self,
        i: u16,
        ray: &RayMsg,
        hit: (u8, Split, [u32; 3]),
        spawned: &Children,
    ) {
        let (children, split, rgb) = hit;
        let mut next = self.scene().candidates();
        for &(k, mut child) in spawned {
            child.credit = split.child(child.kind == RayKind::Reflected);
            if self.pool.admit(child, Stage::Trace).is_err() {
                next = k;
                break;
            }
        }
        self.shaded_up_to(i, ray, Stage::Shade { next, children, split, rgb });
    }

    /// Records how far a hit's children are spawned: the parent retires with
    /// its own share once all are out.
    fn shaded_up_to(&mut self, i: u16, ray: &RayMsg, progress: Stage) {
        let Stage::Shade { next, children, split, rgb } = progress else { return };
        let stage = if next < self.scene().candidates() {
            progress
        } else {
            Stage::Retire(retire(ray, rgb, split.own(ray.credit, children), children))
        };
        self.pool.set_stage(i, stage);
    }

    /// Spawns the rest of a hit's children, evaluated again, while the pool
    /// admits them; retires the parent once all are out.
    pub(super) fn shade(&mut self, i: u16, work: &mut Work) {
        let Some(slot) = self.pool.get(i).copied() else { return };
        let Stage::Shade { mut next, children, split, rgb } = slot.stage() else { return };
        let ray = slot.ray;
        let Ok(line) = Self::line_of(&ray) else {
            return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::ShadeWithoutLine);
        };
        let Some((t, sphere)) = self.hit_sphere(&ray) else {
            return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::ShadeMissesSphere);
        };
        let Some(surface) = Surface::at(&line, t, &sphere) else {
            return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::ShadeWithoutSurface);
        };
        work.shades += 1;
        let candidates = self.scene().candidates();
        while next < candidates {
            if let Some(Child::Ray(mut child)) = self.scene().child(&ray, &line, &surface, &sphere, next) {
                child.credit = split.child(child.kind == RayKind::Reflected);
                if self.pool.admit(child, Stage::Trace).is_err() {
                    break;
                }
            }
            next += 1;
        }
        self.shaded_up_to(i, &ray, Stage::Shade { next, children, split, rgb });
    }
}

fn add3(a: [u32; 3], b: [u32; 3]) -> [u32; 3] {
    [a[0].saturating_add(b[0]), a[1].saturating_add(b[1]), a[2].saturating_add(b[2])]
}

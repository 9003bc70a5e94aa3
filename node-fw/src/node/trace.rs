//! Tracing: one piece of work per poll, a ray walked through the subregion
//! by its digital line until it hits, leaves, or is done.

use link_proto::{ErrorCode, HitMsg, RayKind, RayMsg, Site};

use crate::digital_line::{DigitalLine, wire_cell};
use crate::error::Error;
use crate::geometry::Line;
use crate::limits::Scalar;
use crate::pool::Stage;
use crate::route;
use crate::shading::Scene;
use crate::sphere::Hit;
use crate::subregion::{Outcome, Query, TraceStats};

use super::{Children, Node, Work, retire, retire_to_background};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// One piece of work: the ready ray of the lowest class, else a new
    /// initial ray. Low classes are early in their lives, so serving them
    /// first hands the nodes further on their work soonest: on 8x8x8 with
    /// spheres in the middle, serving the highest class first left nodes there
    /// half idle until late, for a makespan 1.5x the busiest node's time (1.28x
    /// this way). Admission alone keeps the pool deadlock-free; the order only
    /// decides when.
    pub(super) fn compute(&mut self, work: &mut Work) {
        let ready = self.pool.lowest_ready(|slot| self.pool.can_admit(slot.ray.class.saturating_add(1)));
        if let Some(i) = ready {
            match self.pool.get(i).map(|s| s.stage()) {
                Some(Stage::Trace) => self.trace(i, work),
                Some(Stage::Shade { .. }) => self.shade(i, work),
                _ => {}
            }
        } else if self.creation_left() && self.pool.can_admit(0) {
            self.create_initial(work);
        }
    }

    /// What shading needs of the scene.
    pub(super) fn scene(&self) -> Scene<'_> {
        Scene { header: &self.header, grid: &self.grid, lights: &self.lights }
    }

    /// A ray's exact line from its wire form.
    pub(super) fn line_of(ray: &RayMsg) -> Result<Line, Error> {
        Line::from_bits(ray.origin, ray.dir)
    }

    /// Walks ray `i` through the subregion: it leaves for a neighbour, retires,
    /// or hits and is shaded.
    fn trace(&mut self, i: u16, work: &mut Work) {
        let Some(mut ray) = self.pool.get(i).map(|s| s.ray) else { return };
        let line = match Self::line_of(&ray) {
            Ok(line) => line,
            Err(_) => return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::RayWithoutLine),
        };
        let Ok(mut walk) = DigitalLine::resume(&line, wire_cell(ray.cell)) else {
            return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::RayCellOffLine);
        };
        let carried = ray.best;
        let mut best = carried.map(|h| Hit { t: Scalar::from_bits(h.t), sphere: h.sphere.id });
        let query = Query {
            ignore: ray.ignore,
            t_max: ray.t_max.map(Scalar::from_bits),
            any_hit: ray.kind == RayKind::Shadow,
        };
        let mut stats = TraceStats::default();
        let mut spawned = Children::new();
        let outcome = self.region.trace(&line, &mut walk, &mut best, &query, &mut stats);
        work.traces += 1;
        work.cube_steps += stats.cube_steps;
        work.sphere_tests += stats.sphere_tests;
        work.sphere_hits += stats.sphere_hits;
        self.totals.rays += 1;
        self.totals.cube_steps += stats.cube_steps;
        self.totals.sphere_tests += stats.sphere_tests;
        // A hit found here names a sphere this node holds; one carried in keeps
        // the sphere it came with.
        ray.best = match best {
            Some(h) if carried.is_none_or(|c| c.t != h.t.to_bits() || c.sphere.id != h.sphere) => {
                match self.region.sphere(h.sphere) {
                    Some(s) => Some(HitMsg { t: h.t.to_bits(), sphere: s.to_msg() }),
                    None => return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::BestHitUnknown),
                }
            }
            _ => carried,
        };
        let leaves_at = walk.cell();
        let outcome = match outcome {
            // A ray with no hit pending may meet nothing more: then it ends
            // here, as the nodes it would cross would end it.
            Outcome::Leave if ray.best.is_none() => {
                let mut steps = 0;
                work.clear_looks += u32::from(self.occupancy.is_ready());
                let end = self.occupancy.walk_clear(&line, &mut walk, &self.grid, query.t_max, &mut steps);
                work.clear_steps += steps;
                self.totals.cube_steps += steps;
                end.unwrap_or(Outcome::Leave)
            }
            other => other,
        };
        let stage = match outcome {
            Outcome::Leave => {
                ray.cell = leaves_at.map(|c| c as u16);
                // The sphere a secondary ray leaves from goes with it (two
                // bytes a hop) only while a cube ahead may list it.
                if let Some(id) = ray.ignore {
                    work.ignore_looks += 1;
                    if self.region.left_behind(id, leaves_at, ray.dir) {
                        ray.ignore = None;
                    }
                }
                match route::toward(&self.region.owned(), leaves_at, self.driving_axis()) {
                    Some(port) => self.leave_by(port, ray.class),
                    None => return self.fail_at(ErrorCode::BadRay, ray.pixel, Site::LeavesTowardNoNeighbour),
                }
            }
            Outcome::LeftGrid | Outcome::Clear if ray.kind == RayKind::Shadow => {
                Stage::Retire(retire(&ray, ray.weight, ray.credit, 0))
            }
            Outcome::LeftGrid | Outcome::Clear => Stage::Retire(retire_to_background(&self.scene(), &ray)),
            Outcome::Blocked => Stage::Retire(retire(&ray, [0; 3], ray.credit, 0)),
            Outcome::Hit(_) => {
                work.shades += 1;
                match self.begin_shading(&ray, &line, &mut spawned) {
                    Ok(stage) => stage,
                    Err(site) => return self.fail_at(ErrorCode::BadRay, ray.pixel, site),
                }
            }
        };
        self.pool.set_ray(i, ray);
        self.pool.set_stage(i, stage);
        if let Stage::Shade { children, split, rgb, .. } = stage {
            self.spawn_evaluated(i, &ray, (children, split, rgb), &spawned);
        }
    }
}

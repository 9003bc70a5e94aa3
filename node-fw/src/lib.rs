//! Node firmware of the sliding-boundary ray tracer (Nemoto & Omachi, 1986).
//!
//! Each node of an X x Y x Z array owns one box-shaped [`subregion`] of the scene's
//! grid of unit cubes and keeps only the spheres that touch it. Rays walk the
//! grid cube by cube along the exact integer [`digital_line`], are tested against
//! the spheres of each cube with exact wide-integer [`sphere`] hits, and cross to
//! neighbouring nodes as plain integers, so the image never depends on how the
//! grid is partitioned.
//!
//! `no_std`, no allocator, no panics on input: every failure is an [`Error`] value.
//! The fixed-point formats and the ranges in which nothing overflows are in
//! [`limits`].
#![no_std]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

pub mod camera;
pub mod credit;
pub mod cube_box;
pub mod digital_line;
pub mod error;
pub mod framed;
pub mod geometry;
pub mod limits;
pub mod link;
pub mod load;
pub mod node;
pub mod occupancy;
pub mod pool;
pub mod reliable;
pub mod route;
pub mod shading;
pub mod slide;
pub mod sphere;
pub mod subregion;
pub mod wide;
pub mod window;
pub mod wiring;

pub use cube_box::CubeBox;
pub use digital_line::DigitalLine;
pub use error::{Error, Field};
pub use geometry::{Direction, Grid, Line, Point};
pub use link::{Links, Port};
pub use load::{Load, LoadMeter};
pub use node::{Node, Totals, Work};
pub use sphere::{Hit, Material, Root, Sphere};
pub use subregion::{Outcome, Query, Rejected, Subregion, TraceStats};

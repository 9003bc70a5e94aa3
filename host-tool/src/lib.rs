//! The host of the sliding-boundary ray tracer: it describes and validates
//! scenes, partitions the grid over the array, broadcasts the scene, collects
//! pixel contributions into images, and drives runs on the in-memory board.
//! An independent f64 renderer ([`mod@reference`]) checks the fixed-point image.

pub mod args;
pub mod backend;
pub mod boards;
pub mod cabling;
pub mod camera;
pub mod compare;
pub mod cost_map;
pub mod direct;
pub mod entry;
pub mod error;
pub mod fit;
pub mod frame;
pub mod history;
pub mod links;
pub mod output;
pub mod partition;
pub mod plot;
pub mod qemu;
pub mod reference;
pub mod relay;
pub mod render;
pub mod run_files;
pub mod scene;
pub mod serial;

pub use error::HostError;

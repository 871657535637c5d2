//! `[controller] error_frame` through the binary, in one test executable (one link for CI):
//! moved flights and the world form's warning, the papers' form pinned byte for byte, and the
//! error_frame Monte Carlo (`plant_sim frames`).

#[path = "../common/mod.rs"]
mod common;

mod frames;
mod moved;
mod pinned_world;

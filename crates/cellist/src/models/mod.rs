//! Models: a state, one step, and the observables of each kind of particle system.

pub mod billiards;
pub mod gravity;
pub mod md;
pub mod model;
pub mod pse;
pub mod vortex;
pub mod vortex3;

pub use model::{
    check, whole_frame, Blowup, Checked, CheckedArray, Field, Ids, Model, ModelInfo, ParticleBlock,
    Particles,
};

//! Each model's scenario section: its keys, checked, become an engine model, the
//! outputs it writes and the physics a checkpoint records.

pub mod billiards;
pub mod field_output;
pub mod gravity;
pub mod md;
pub mod pse;
pub mod vortex;

//! How many joints a spatial arm may have here: one leaf both the arm files' reader and the
//! URDF reader check against.

/// The most joints a spatial arm may have here (the record and the CSV carry this many).
pub const MAX_JOINTS: usize = 8;
/// The fewest joints a spatial arm needs (the task has six dimensions).
pub const MIN_SPATIAL_JOINTS: usize = 6;

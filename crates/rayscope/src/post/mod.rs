//! Post-processes on the finished linear image (the film's values, before clamping and
//! encoding): [`bloom`], a glow around bright pixels. They run once per written or shown
//! image, never per sample, and are off by default.

pub mod bloom;

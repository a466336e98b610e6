#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![deny(unsafe_code)]

pub mod camera;
pub mod math;
#[cfg(feature = "plot")]
pub mod plot;
pub mod target;

#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![deny(unsafe_code)]

pub mod math;
pub mod camera;
pub mod target;
pub mod feature;

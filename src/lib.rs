#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![deny(unsafe_code)]

pub mod camera;
pub mod feature;
pub mod math;
pub mod target;

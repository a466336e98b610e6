#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![deny(unsafe_code)]

pub mod avoidance;
pub mod camera;
pub mod continuity;
pub mod controller;
pub mod depth;
pub mod feature;
pub mod law;
pub mod linalg;
pub mod math;
pub mod measurement;
#[cfg(feature = "plot")]
pub mod plot;
pub mod report;
pub mod robot;
pub mod scenario;
pub mod sim;
pub mod stack;
pub mod target;
pub mod task;
pub mod visual_task;

#![doc = include_str!("../README.md")]
#![warn(missing_docs)]
#![deny(unsafe_code)]
#![cfg_attr(docsrs, feature(doc_cfg))]

pub mod avoidance;
pub mod bounds;
pub mod camera;
pub mod continuity;
pub mod controller;
pub mod depth;
pub mod feature;
#[doc(hidden)]
pub mod fuzz;
pub mod law;
pub mod linalg;
pub mod math;
pub mod measurement;
#[cfg(feature = "plot")]
pub mod plot;
pub mod report;
pub mod robot;
pub mod scenario;
pub mod servo;
pub mod sim;
pub mod stack;
pub mod study;
pub mod target;
pub mod task;
pub mod visual_task;

#[doc = include_str!("../docs/theory.md")]
pub mod theory {
    #[doc = include_str!("../docs/peer_scene.md")]
    pub mod peer_scene {}
}

/// Guides: the tasks a user meets first, each with code that compiles.
pub mod guide {
    #[doc = include_str!("../docs/guide/your_robot.md")]
    pub mod your_robot {}
    #[doc = include_str!("../docs/guide/reading_results.md")]
    pub mod reading_results {}
    #[doc = include_str!("../docs/guide/camera_loop.md")]
    pub mod camera_loop {}
    #[doc = include_str!("../docs/guide/tuning.md")]
    pub mod tuning {}
}

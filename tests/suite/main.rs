//! The integration tests: one module per subject, compiled into one test binary.
//!
//! One binary rather than one per file because most of CI's time is compiling and linking: each integration-test
//! binary links the whole dependency tree again and instantiates the crate's generic code (the simulation, the
//! controller, the kinematics for each joint count) again. `tests/run_log.rs` keeps a binary of its own, because it
//! measures the peak of the heap over all threads with its own global allocator.
//!
//! This binary's global allocator is [`counting_allocator`]'s, which counts allocations per thread: a
//! zero-allocation test counts only what its own thread allocates, whatever the other tests do meanwhile.
//!
//! Run one subject with `cargo test --test suite servo::` (a module name followed by `::`).

mod counting_allocator;
mod law_fixture;
mod obstacle_fixture;
#[path = "../../benches/common/servo_loop.rs"]
mod servo_loop;

mod allocation;
mod calibration;
mod calibration_opencv;
mod camera_target;
mod citations;
mod controller_escape;
mod controller_synthetic;
mod convergence_domain;
mod depth_estimation;
mod foundation_errors;
mod fuzz;
mod hostile_input;
mod hostile_readers;
mod hqp;
mod measurement_no_alloc;
mod noisy_camera_loop;
mod obstacle_scenario;
mod obstacles;
mod obstacles_no_alloc;
mod paper_experiment;
mod peer_variants;
mod readme;
mod real_camera_scenario;
mod robot_kinematics;
mod robot_urdf_errors;
mod scenario_fields;
mod scenario_generate;
mod scenarios;
mod servo;
mod servo_acceleration;
mod servo_methods;
mod servo_observer;
mod sim_acceleration;
mod sns;
mod square_target;
mod stack_properties;
mod straight_feasible;
mod study_shards;
mod visual_task_jacobian;
mod your_robot;
mod zoo_restart;

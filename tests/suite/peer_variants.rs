//! The peer variants do the work docs/peer_scene.md says they do: in C the full-rank point task leaves no free
//! direction, so the avoidance term is zero; in CL (ViSP's large projection operator) it is computed and applied while
//! joint 4 is in its activation band and `‖e‖ > 0.1`, as ViSP's is; every variant servos.

use crate::servo_loop::{ServoLoop, Variant};

/// Runs one episode of 1000 steps; returns the number of steps with a non-zero avoidance term and the final `‖e‖`.
fn episode(variant: Variant) -> (usize, f64) {
    let mut servo = ServoLoop::peer(variant);
    let mut active = 0;
    for _ in 0..1000 {
        servo.step();
        let avoidance = servo.avoidance().expect("bare law");
        if avoidance.norm() > 0.0 {
            active += 1;
        }
    }
    (active, servo.error_norm())
}

#[test]
fn c_applies_no_avoidance_and_cl_does() {
    let (active_c, error_c) = episode(Variant::C);
    assert_eq!(active_c, 0, "C: P^A = 0 for the full-rank point task");
    let (active_cl, error_cl) = episode(Variant::CL);
    assert!(
        active_cl >= 20,
        "CL: the avoidance acted at {active_cl} steps only"
    );
    assert!(
        active_cl < 1000,
        "CL: near the goal (‖e‖ < 0.1) the kernel projector alone acts"
    );
    // Both servo (the norm-preserving projection leaves the decay of ‖e‖ to the task).
    assert!(
        error_c < 5e-3 && error_cl < 5e-3,
        "C {error_c}, CL {error_cl}"
    );
}

//! The feature computations allocate nothing on the heap (DESIGN principle 2): counted with a global allocator.

use nalgebra::{Dyn, OMatrix, U6};
use servostack::camera::ImagePoint;
use servostack::feature::{
    AreaNormalization, Centroid, DiagonalAngle, Feature, FeatureSet, InteractionSource, Observation,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: forwards the caller's layout to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn feature_computations_do_not_allocate() {
    let desired = [(-0.2, -0.1), (0.2, -0.1), (0.2, 0.1), (-0.2, 0.1)]
        .map(|(x, y)| ImagePoint::new(x, y, 0.5));
    let desired = Observation::new(&desired, None).unwrap();
    let n = AreaNormalization::from_desired(&desired, 0.5).unwrap();
    let sets = [
        FeatureSet::paper_full(Centroid::new(0.5).unwrap(), DiagonalAngle::default(), n),
        FeatureSet::visp_moments(n),
    ];
    let current = [(-0.21, -0.09), (0.19, -0.11), (0.2, 0.12), (-0.2, 0.1)]
        .map(|(x, y)| ImagePoint::new(x, y, 0.52));
    let (mut s, mut s_star, mut e) = ([0.0; 6], [0.0; 6], [0.0; 6]);
    let mut l = OMatrix::<f64, Dyn, U6>::zeros(6);

    let before = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(before > 0, "the counter sees the set-up allocations");
    for set in &sets {
        set.value(&desired, &mut s_star).unwrap();
        let obs = Observation::new(&current, None).unwrap();
        set.value(&obs, &mut s).unwrap();
        for source in [InteractionSource::Exact, InteractionSource::PaperApprox] {
            set.interaction(&obs, source, l.rows_mut(0, 6)).unwrap();
        }
        set.interaction(&desired, InteractionSource::Desired, l.rows_mut(0, 6))
            .unwrap();
        set.error(&s, &s_star, &mut e).unwrap();
    }
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst) - before, 0);
}

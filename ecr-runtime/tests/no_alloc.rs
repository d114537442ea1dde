//! A step of a fixed-order stepper with static dimension allocates nothing: counted by a
//! global allocator wrapper. (One test in this binary, so no other thread allocates meanwhile.)

use ecr_runtime::ecr_method;
use ecr_runtime::operator::DenseStatic;
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::Semilinear;
use nalgebra::SMatrix;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

ecr_method!(r = 3);

#[test]
fn steps_allocate_nothing() {
    let (omega, k) = (5.0_f64, 0.07_f64);
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let mut fixed: Ec3<_, 2> =
        Ec3::fixed(Semilinear::new(DenseStatic::new(a).unwrap(), g), 0.01).unwrap();
    let mut run_time =
        EcStepper::new(Semilinear::new(DenseStatic::new(a).unwrap(), g), 3, 0.01).unwrap();
    let mut y = [0.0, omega];
    let mut z = [0.0, omega];
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for _ in 0..1000 {
        fixed.step(&mut y).unwrap();
        run_time.step(&mut z).unwrap();
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(after - before, 0, "heap allocations during 2000 steps");
    assert_eq!(y, z);
}

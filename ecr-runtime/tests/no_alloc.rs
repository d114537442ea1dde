//! A step of a fixed-order stepper with static dimension allocates nothing: counted by a
//! global allocator wrapper, per thread (the test harness allocates on its own threads while a
//! test runs).

use ecr_runtime::ecr_method;
use ecr_runtime::operator::DenseStatic;
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::Semilinear;
use nalgebra::SMatrix;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    /// Allocations made by this thread.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the slot may be gone while the thread exits.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn the_counter_counts() {
    let before = allocations();
    let v = std::hint::black_box(vec![1.0_f64; 3]);
    assert_eq!(allocations() - before, 1);
    drop(v);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

ecr_method!(r = 3);
ecr_method!(r = 3, family = tc);

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
    let before = allocations();
    for _ in 0..1000 {
        fixed.step(&mut y).unwrap();
        run_time.step(&mut z).unwrap();
    }
    let after = allocations();
    assert_eq!(after - before, 0, "heap allocations during 2000 steps");
    assert_eq!(y, z);
}

#[test]
fn second_order_steps_allocate_nothing() {
    use ecr_runtime::problems::Fpu;
    use ecr_runtime::second_order::{Omega, SecondOrder, TcStepper};
    // One mode (fused sweeps, fixed-size storage) and six modes (the oscillator bank's
    // combine, run-time storage).
    let k2 = 0.07_f64 * 0.07;
    let sys = SecondOrder::new(
        Omega::scalar(25.0 + k2, 1).unwrap(),
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
    );
    let mut fixed: Tc3<_, 1> = Tc3::fixed(&sys, 0.01).unwrap();
    let fpu = Fpu::new(3, 50.0).unwrap();
    let mut chain = TcStepper::new(fpu.system().unwrap(), 3, 0.01).unwrap();
    let (mut q, mut p) = ([0.0], [5.0]);
    let (mut qc, mut pc) = fpu.initial_value();
    let before = allocations();
    for _ in 0..1000 {
        fixed.step(&mut q, &mut p).unwrap();
    }
    for _ in 0..1000 {
        chain.step(&mut qc, &mut pc).unwrap();
    }
    let after = allocations();
    assert_eq!(after - before, 0, "heap allocations during 2000 steps");
}

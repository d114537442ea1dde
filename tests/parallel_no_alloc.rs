//! Steps on the concurrent stage path allocate nothing after the first, counted on the test's
//! thread and on every thread of rayon's pool: a global allocator wrapper counts the threads
//! that this file marks (its test thread, and rayon's workers through the pool's start
//! handler). One test in this file, so that the pool is configured before anything uses it.
//!
//! What rayon itself allocates is accounted for separately: its threads start once (before
//! the counted steps), and a thread outside the pool hands each concurrent section to the pool
//! through rayon's queue for outside jobs (crossbeam-deque's `Injector`), which allocates a
//! block of slots every 63 jobs. Steps run on a thread of the pool (`rayon::scope`,
//! `ThreadPool::install`) hand nothing through that queue and allocate nothing at all.

use ecr::problems::Nls;
use ecr_runtime::stepper::{EcStepper, Predictor, SolverSettings};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

/// Allocations by the marked threads.
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
/// The size of the last allocation by a marked thread.
static LAST_SIZE: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations count.
    static MARKED: Cell<bool> = const { Cell::new(false) };
}

fn count(size: usize) {
    // `try_with`: the slot may be gone while the thread exits.
    if MARKED.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        LAST_SIZE.store(size, Ordering::Relaxed);
    }
}

fn mark() {
    MARKED.with(|m| m.set(true));
}

fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::Relaxed)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// EC3P on the NLS with N = 2^12 on the concurrent path, after three warm-up steps.
fn stepper(predictor: Predictor) -> (EcStepper<ecr::problems::NlsSystem>, Vec<f64>) {
    let nls = Nls::new(1 << 12).unwrap();
    let settings = SolverSettings {
        predictor,
        parallel_min_dim: 0,
        ..SolverSettings::default()
    };
    let mut st = EcStepper::with_nodes(nls.system().unwrap(), 3, 3, 0.005, settings).unwrap();
    let mut y = nls.initial_value();
    for _ in 0..3 {
        st.step(&mut y).unwrap();
    }
    (st, y)
}

const STEPS: usize = 100;

#[test]
fn concurrent_steps_allocate_nothing() {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .start_handler(|_| mark())
        .build_global()
        .expect("the global pool is configured here first");
    mark();
    // The counter counts, on this thread and on a worker.
    let before = allocations();
    let v = std::hint::black_box(vec![1.0_f64; 3]);
    let w = rayon::join(|| (), || std::hint::black_box(vec![2.0_f64; 3])).1;
    assert!(allocations() - before >= 2);
    drop((v, w));

    for predictor in [Predictor::Constant, Predictor::Extrapolate] {
        // On a thread of the pool: nothing.
        let (mut st, mut y) = stepper(predictor);
        let counted = rayon::scope(|_| {
            let before = allocations();
            for _ in 0..STEPS {
                st.step(&mut y).unwrap();
            }
            allocations() - before
        });
        assert_eq!(
            counted, 0,
            "{predictor:?}: heap allocations during {STEPS} concurrent steps in the pool"
        );

        // From outside the pool: only the blocks of rayon's queue for outside jobs, all of one
        // size, fewer than one per two steps (each step hands the pool a few jobs per sweep,
        // the queue takes a block per 63).
        let (mut st, mut y) = stepper(predictor);
        let mut sizes = Vec::with_capacity(STEPS);
        let before = allocations();
        for _ in 0..STEPS {
            let n = allocations();
            st.step(&mut y).unwrap();
            if allocations() > n {
                sizes.push(LAST_SIZE.load(Ordering::Relaxed));
            }
        }
        let counted = allocations() - before;
        println!(
            "{predictor:?}: {counted} allocations in {STEPS} steps from outside the pool, of \
             sizes {sizes:?}"
        );
        assert!(
            counted <= STEPS / 2,
            "{predictor:?}: {counted} allocations in {STEPS} steps from outside the pool"
        );
        assert!(
            sizes.windows(2).all(|s| s[0] == s[1]),
            "{predictor:?}: allocations of several sizes from outside the pool: {sizes:?}"
        );
    }
}

//! Where a stepper keeps its stage state ([`Buffers`]): on the heap, allocated once
//! ([`VecBuffers`]), or in fixed-size arrays with the per-step state local to each step
//! ([`StaticBuffers`]).

use crate::error::{Error, Result};

/// Mutable views of a stepper's stage state: y₀ (d), stages and their next iterate (s·d),
/// g at the stages (s·d), moments (r·d), each stage or moment contiguous, and scratch.
pub struct BufferParts<'a> {
    /// The state at the start of the step.
    pub y0: &'a mut [f64],
    /// Stage values Y₁..Y_s.
    pub stages: &'a mut [f64],
    /// The next fixed-point iterate of the stages.
    pub new_stages: &'a mut [f64],
    /// The propagated start `e^{cᵢhA} y₀` of each stage (s·d; fused sweeps only).
    pub props: &'a mut [f64],
    /// g(Y₁)..g(Y_s).
    pub g: &'a mut [f64],
    /// Moments G₀..G_{r−1}.
    pub moments: &'a mut [f64],
    /// The state at the end of the last step (d).
    pub last: &'a mut [f64],
    /// The rounding error of the last step's compensated update (d), carried into the next.
    pub comp: &'a mut [f64],
    /// Scratch for the end of a step (3d): the double-double propagated state and the
    /// propagated rounding error.
    pub tmp: &'a mut [f64],
}

/// Storage for the stage state of a [`Stepper`](super::Stepper).
pub trait Buffers: Sized {
    /// Storage for r moments, s stages, dimension d.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if fixed-size storage does not have these sizes.
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self>;
    /// The dimension d.
    fn dim(&self) -> usize;
    /// Calls `f` with all buffers, mutably. Fixed-size storage hands out the per-step state
    /// (stages, their next iterate, the propagated starts, g) as arrays local to the call, so
    /// that the compiler can keep them in registers; their contents are not kept from one call
    /// to the next (the step does not need them).
    fn with_parts<R>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R) -> R;
    /// Whether the stages, their next iterate and g are local arrays (see
    /// [`with_parts`](Self::with_parts)). The step then lets only `props` and `tmp` reach
    /// functions that are not inlined (the φ-bank), routing their results through a copy, so
    /// that the others can stay in registers.
    const LOCAL_STAGES: bool = false;
    /// y₀ of the last step.
    fn y0(&self) -> &[f64];
    /// The moments of the last step.
    fn moments(&self) -> &[f64];
    /// The stage values of the last step's final iterate (s·d), where the storage keeps them
    /// from one step to the next (heap buffers; fixed-size storage does not).
    fn stages(&self) -> Option<&[f64]> {
        None
    }
    /// The state the last step returned (d), where the storage can hand it out.
    fn last_state(&self) -> Option<&[f64]> {
        None
    }
    /// (r, s, d) where they are compile-time constants (fixed-size storage), so that a step's
    /// loops over them unroll.
    const SIZES: Option<(usize, usize, usize)> = None;
}

/// Heap buffers, allocated once at construction (any d known at run time).
#[derive(Clone, Debug)]
pub struct VecBuffers {
    y0: Vec<f64>,
    stages: Vec<f64>,
    new_stages: Vec<f64>,
    props: Vec<f64>,
    g: Vec<f64>,
    moments: Vec<f64>,
    last: Vec<f64>,
    comp: Vec<f64>,
    tmp: Vec<f64>,
}

impl Buffers for VecBuffers {
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self> {
        Ok(VecBuffers {
            y0: vec![0.0; d],
            stages: vec![0.0; s * d],
            new_stages: vec![0.0; s * d],
            props: vec![0.0; s * d],
            g: vec![0.0; s * d],
            moments: vec![0.0; r * d],
            last: vec![0.0; d],
            comp: vec![0.0; d],
            tmp: vec![0.0; 3 * d],
        })
    }
    fn dim(&self) -> usize {
        self.y0.len()
    }
    fn with_parts<R>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R) -> R {
        f(BufferParts {
            y0: &mut self.y0,
            stages: &mut self.stages,
            new_stages: &mut self.new_stages,
            props: &mut self.props,
            g: &mut self.g,
            moments: &mut self.moments,
            last: &mut self.last,
            comp: &mut self.comp,
            tmp: &mut self.tmp,
        })
    }
    fn y0(&self) -> &[f64] {
        &self.y0
    }
    fn moments(&self) -> &[f64] {
        &self.moments
    }
    fn stages(&self) -> Option<&[f64]> {
        Some(&self.stages)
    }
    fn last_state(&self) -> Option<&[f64]> {
        Some(&self.last)
    }
}

/// Fixed-size buffers for dimension `B·D` (B blocks of D: `B = 2` holds the state (q, p) of a
/// second-order system with D positions), `S` stages and `R` moments: what a step hands on
/// (y₀, the moments, the end state and its rounding error) in arrays inside the stepper, the
/// stage state in arrays on the stack of each step (see [`Buffers::with_parts`]); no heap.
#[derive(Clone, Debug)]
pub struct StaticBuffers<const D: usize, const S: usize, const R: usize, const B: usize = 1> {
    y0: [[f64; D]; B],
    moments: [[[f64; D]; B]; R],
    last: [[f64; D]; B],
    comp: [[f64; D]; B],
}

impl<const D: usize, const S: usize, const R: usize, const B: usize> Buffers
    for StaticBuffers<D, S, R, B>
{
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self> {
        for (what, expected, found) in [
            ("dimension", B * D, d),
            ("stages s", S, s),
            ("moments r", R, r),
        ] {
            if expected != found {
                return Err(Error::DimensionMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        Ok(StaticBuffers {
            y0: [[0.0; D]; B],
            moments: [[[0.0; D]; B]; R],
            last: [[0.0; D]; B],
            comp: [[0.0; D]; B],
        })
    }
    fn dim(&self) -> usize {
        B * D
    }
    #[inline(always)]
    fn with_parts<R2>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R2) -> R2 {
        let mut stages = [[[0.0; D]; B]; S];
        let mut new_stages = [[[0.0; D]; B]; S];
        let mut props = [[[0.0; D]; B]; S];
        let mut g = [[[0.0; D]; B]; S];
        let mut tmp = [[[0.0; D]; B]; 3];
        f(BufferParts {
            y0: self.y0.as_flattened_mut(),
            stages: stages.as_flattened_mut().as_flattened_mut(),
            new_stages: new_stages.as_flattened_mut().as_flattened_mut(),
            props: props.as_flattened_mut().as_flattened_mut(),
            g: g.as_flattened_mut().as_flattened_mut(),
            moments: self.moments.as_flattened_mut().as_flattened_mut(),
            last: self.last.as_flattened_mut(),
            comp: self.comp.as_flattened_mut(),
            tmp: tmp.as_flattened_mut().as_flattened_mut(),
        })
    }
    const LOCAL_STAGES: bool = true;
    fn y0(&self) -> &[f64] {
        self.y0.as_flattened()
    }
    fn moments(&self) -> &[f64] {
        self.moments.as_flattened().as_flattened()
    }
    const SIZES: Option<(usize, usize, usize)> = Some((R, S, B * D));
}

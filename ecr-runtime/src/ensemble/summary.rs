//! A [`Summary`] of an ensemble's outputs without keeping them: per output component at each
//! output time, the count, mean, variance, minimum, maximum and chosen quantiles (what
//! SciML's `EnsembleSummary` gives), in memory that does not grow with the members.
//!
//! # Accuracy
//!
//! - Count, minimum and maximum are exact; mean and variance are Welford's running updates
//!   (one rounding per member and statistic; the values are added in member order, so that
//!   the same members give the same bits on any number of threads).
//! - Quantiles come from a logarithmic histogram (the DDSketch of Masson, Rim and Lee, 2019):
//!   a value x ≠ 0 falls into bucket ⌈log_γ |x|⌉ with γ = (1 + α)/(1 − α), α =
//!   [`Summary::RELATIVE_ACCURACY`] = 10⁻³, per sign, zeros counted apart. The q-quantile
//!   returned is within a relative 10⁻³ of the exact one (the order statistic of rank
//!   ⌊q (n − 1)⌋ of the n values), and clamped to [min, max] (q = 0 and q = 1 give min and
//!   max exactly). The histogram holds at most one bucket per 0.2 % of range a value can take
//!   (about 1 150 per decade of magnitude in use, 12 bytes each) and never more than
//!   [`Summary::MAX_BUCKETS`]; beyond that the buckets of the smallest magnitudes are joined
//!   (their quantiles are then only as good as that joined bucket; with values spanning
//!   fewer than 50 decades it never happens). The counts do not depend on the order in which
//!   values come, so summaries [merged](Summary::merge) give the same quantiles as one.
//! - Values that are NaN or infinite are counted ([`Stat::non_finite`]) and left out of the
//!   rest.

use std::collections::BTreeMap;

use crate::error::{Error, Result};

/// Statistics over members of each output component at each output time.
#[derive(Clone, Debug)]
pub struct Summary {
    times: usize,
    components: usize,
    quantiles: Vec<f64>,
    members: u64,
    slots: Vec<Slot>,
}

#[derive(Clone, Debug, Default)]
struct Slot {
    count: u64,
    non_finite: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
    sketch: Sketch,
}

/// Bucket counts of positive and negative values (by ⌈log_γ |x|⌉) and zeros.
#[derive(Clone, Debug, Default)]
struct Sketch {
    positive: BTreeMap<i32, u64>,
    negative: BTreeMap<i32, u64>,
    zeros: u64,
}

/// What a [`Summary`] knows of one output component at one output time.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    /// The finite values summarised.
    pub count: u64,
    /// Values that were NaN or infinite (left out of everything else).
    pub non_finite: u64,
    /// Their mean (NaN without values).
    pub mean: f64,
    /// Their sample variance (divided by count − 1; NaN for fewer than two values).
    pub variance: f64,
    /// The smallest (NaN without values).
    pub min: f64,
    /// The largest (NaN without values).
    pub max: f64,
    /// The quantiles asked for, in the order given: (q, value), the value within a relative
    /// [`Summary::RELATIVE_ACCURACY`] of the exact one (NaN without values).
    pub quantiles: Vec<(f64, f64)>,
}

impl Summary {
    /// The relative accuracy α of the quantiles.
    pub const RELATIVE_ACCURACY: f64 = 1e-3;

    /// The most buckets a component's histogram keeps (12 bytes each, and a tree's overhead).
    pub const MAX_BUCKETS: usize = 1 << 16;

    /// A summary of `times` × `components` values per member (time-major: value `j` of a
    /// member is component `j % components` at time `j / components`), with the quantiles
    /// `quantiles` (each in [0, 1]).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a quantile outside [0, 1] or NaN, no values per member, or
    /// more than 2²⁰ of them (each keeps a histogram).
    pub fn new(times: usize, components: usize, quantiles: &[f64]) -> Result<Self> {
        if let Some(q) = quantiles.iter().find(|q| !(0.0..=1.0).contains(*q)) {
            return Err(Error::InvalidInput(format!(
                "quantile {q:?}: quantiles are in [0, 1]"
            )));
        }
        let slots = times.checked_mul(components).filter(|&n| n <= 1 << 20);
        let Some(slots) = slots.filter(|&n| n > 0) else {
            return Err(Error::InvalidInput(format!(
                "a summary of {times} times × {components} components: between 1 and 2^20 \
                 values per member"
            )));
        };
        Ok(Summary {
            times,
            components,
            quantiles: quantiles.to_vec(),
            members: 0,
            slots: vec![Slot::default(); slots],
        })
    }

    /// The number of values per member (times × components).
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether no member was added.
    pub fn is_empty(&self) -> bool {
        self.members == 0
    }

    /// The output times and components per time.
    pub fn shape(&self) -> (usize, usize) {
        (self.times, self.components)
    }

    /// The quantiles asked for.
    pub fn quantiles(&self) -> &[f64] {
        &self.quantiles
    }

    /// The members added.
    pub fn members(&self) -> u64 {
        self.members
    }

    /// Adds one member's values ([`len`](Self::len) of them, time-major).
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for another number of values (nothing is added then).
    pub fn add(&mut self, values: &[f64]) -> Result<()> {
        if values.len() != self.slots.len() {
            return Err(Error::DimensionMismatch {
                what: "a member's values and the summary",
                expected: self.slots.len(),
                found: values.len(),
            });
        }
        self.members += 1;
        for (slot, &x) in self.slots.iter_mut().zip(values) {
            slot.add(x);
        }
        Ok(())
    }

    /// Adds the members of `other` (a summary of other members of the same shape and
    /// quantiles): counts, extremes and quantiles as if they had been added here; mean and
    /// variance by Chan's update, which may differ in the last bits from adding the values
    /// one by one.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if the shapes or quantiles differ.
    pub fn merge(&mut self, other: &Summary) -> Result<()> {
        if self.shape() != other.shape() || self.quantiles != other.quantiles {
            return Err(Error::InvalidInput(
                "summaries of different shapes or quantiles cannot be merged".into(),
            ));
        }
        self.members += other.members;
        for (a, b) in self.slots.iter_mut().zip(&other.slots) {
            a.merge(b);
        }
        Ok(())
    }

    /// The statistics of `component` at output time `time`.
    ///
    /// # Panics
    /// If `time` or `component` is out of range.
    pub fn get(&self, time: usize, component: usize) -> Stat {
        assert!(time < self.times && component < self.components);
        self.slots[time * self.components + component].stat(&self.quantiles)
    }
}

/// γ and ln γ of the histogram.
fn gamma_ln() -> f64 {
    let a = Summary::RELATIVE_ACCURACY;
    ((1.0 + a) / (1.0 - a)).ln()
}

impl Slot {
    fn add(&mut self, x: f64) {
        if !x.is_finite() {
            self.non_finite += 1;
            return;
        }
        self.count += 1;
        if self.count == 1 {
            (self.min, self.max, self.mean, self.m2) = (x, x, x, 0.0);
        } else {
            self.min = self.min.min(x);
            self.max = self.max.max(x);
            let delta = x - self.mean;
            self.mean += delta / self.count as f64;
            self.m2 += delta * (x - self.mean);
        }
        self.sketch.add(x, 1);
    }

    fn merge(&mut self, b: &Slot) {
        self.non_finite += b.non_finite;
        if b.count == 0 {
            return;
        }
        if self.count == 0 {
            let non_finite = self.non_finite;
            *self = b.clone();
            self.non_finite = non_finite;
            return;
        }
        let (na, nb) = (self.count as f64, b.count as f64);
        let n = na + nb;
        let delta = b.mean - self.mean;
        self.mean += delta * nb / n;
        self.m2 += b.m2 + delta * delta * na * nb / n;
        self.count += b.count;
        self.min = self.min.min(b.min);
        self.max = self.max.max(b.max);
        for (&k, &c) in &b.sketch.positive {
            *self.sketch.positive.entry(k).or_insert(0) += c;
        }
        for (&k, &c) in &b.sketch.negative {
            *self.sketch.negative.entry(k).or_insert(0) += c;
        }
        self.sketch.zeros += b.sketch.zeros;
        self.sketch.bound();
    }

    fn stat(&self, quantiles: &[f64]) -> Stat {
        let none = self.count == 0;
        let or_nan = |v: f64| if none { f64::NAN } else { v };
        Stat {
            count: self.count,
            non_finite: self.non_finite,
            mean: or_nan(self.mean),
            variance: if self.count >= 2 {
                self.m2 / (self.count - 1) as f64
            } else {
                f64::NAN
            },
            min: or_nan(self.min),
            max: or_nan(self.max),
            quantiles: quantiles
                .iter()
                .map(|&q| {
                    // The order statistics of the first and last ranks are the extremes,
                    // known exactly (a bucket's value is only within α of them).
                    let rank = (q * (self.count.max(1) - 1) as f64).floor() as u64;
                    let v = if none {
                        f64::NAN
                    } else if rank == 0 {
                        self.min
                    } else if rank + 1 == self.count {
                        self.max
                    } else {
                        self.sketch
                            .quantile(q, self.count)
                            .clamp(self.min, self.max)
                    };
                    (q, v)
                })
                .collect(),
        }
    }
}

impl Sketch {
    fn add(&mut self, x: f64, n: u64) {
        if x == 0.0 {
            self.zeros += n;
            return;
        }
        let key = (x.abs().ln() / gamma_ln()).ceil() as i32;
        let side = if x > 0.0 {
            &mut self.positive
        } else {
            &mut self.negative
        };
        *side.entry(key).or_insert(0) += n;
        if side.len() > Summary::MAX_BUCKETS {
            self.bound();
        }
    }

    /// Joins the smallest-magnitude buckets of a side above [`Summary::MAX_BUCKETS`].
    fn bound(&mut self) {
        for side in [&mut self.positive, &mut self.negative] {
            while side.len() > Summary::MAX_BUCKETS {
                let (k0, c0) = side.pop_first().expect("more than one bucket");
                *side.first_entry().expect("more than one bucket").get_mut() += c0;
                let _ = k0;
            }
        }
    }

    /// The value of the bucket holding the order statistic of rank ⌊q (n − 1)⌋.
    fn quantile(&self, q: f64, n: u64) -> f64 {
        let rank = (q * (n - 1) as f64).floor() as u64;
        let value = |key: i32| {
            let g = gamma_ln();
            // The middle (in relative terms) of (γ^(k−1), γ^k]: 2γ^k / (γ + 1).
            2.0 * (key as f64 * g).exp() / (g.exp() + 1.0)
        };
        let mut seen = 0;
        for (&k, &c) in self.negative.iter().rev() {
            seen += c;
            if seen > rank {
                return -value(k);
            }
        }
        seen += self.zeros;
        if seen > rank {
            return 0.0;
        }
        for (&k, &c) in &self.positive {
            seen += c;
            if seen > rank {
                return value(k);
            }
        }
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_extremes_and_quantiles_of_known_values() {
        let mut s = Summary::new(1, 2, &[0.0, 0.1, 0.5, 0.9, 1.0]).unwrap();
        // Component 0: 1..=1000; component 1: −500..=499 with a NaN.
        for i in 1..=1000 {
            s.add(&[i as f64, i as f64 - 501.0]).unwrap();
        }
        s.add(&[f64::NAN, 7.0]).unwrap_or(());
        let a = s.get(0, 0);
        assert_eq!(a.count, 1000);
        assert_eq!(a.non_finite, 1);
        assert_eq!((a.min, a.max), (1.0, 1000.0));
        assert!((a.mean - 500.5).abs() < 1e-12);
        // Variance of 1..=n: n(n + 1)/12.
        assert!((a.variance - 1000.0 * 1001.0 / 12.0).abs() < 1e-6);
        for (&(q, v), exact) in a.quantiles.iter().zip([1.0, 100.0, 500.0, 900.0, 1000.0]) {
            assert!(
                (v - exact).abs() <= Summary::RELATIVE_ACCURACY * exact,
                "q = {q}: {v} against {exact}"
            );
        }
        let b = s.get(0, 1);
        assert_eq!((b.min, b.max), (-500.0, 499.0));
        let median = b.quantiles[2].1;
        // Rank ⌊0.5 · 1000⌋ = 500 of −500..=500 (7 added): the value 0.
        assert!(median.abs() <= 1.0, "{median}");
        assert!(Summary::new(1, 1, &[1.5]).is_err());
        assert!(Summary::new(0, 1, &[0.5]).is_err());
        assert!(s.add(&[1.0]).is_err());
    }

    #[test]
    fn merged_summaries_give_the_quantiles_of_one() {
        let values: Vec<f64> = (0..5000)
            .map(|i| ((i * 7919) % 5000) as f64 * 1e-3 - 1.0)
            .collect();
        let mut whole = Summary::new(1, 1, &[0.25, 0.5, 0.75]).unwrap();
        let mut parts = [
            Summary::new(1, 1, &[0.25, 0.5, 0.75]).unwrap(),
            Summary::new(1, 1, &[0.25, 0.5, 0.75]).unwrap(),
        ];
        for (i, &v) in values.iter().enumerate() {
            whole.add(&[v]).unwrap();
            parts[i % 2].add(&[v]).unwrap();
        }
        let [mut a, b] = parts;
        a.merge(&b).unwrap();
        let (w, m) = (whole.get(0, 0), a.get(0, 0));
        assert_eq!(w.quantiles, m.quantiles);
        assert_eq!((w.count, w.min, w.max), (m.count, m.min, m.max));
        assert!((w.mean - m.mean).abs() < 1e-12 && (w.variance - m.variance).abs() < 1e-9);
    }
}

//! What a stepper builds for one step size — the kernel bank, its combine coefficients and the
//! fused maps ([`Built`]) — and the cache that lets several steppers of one system share it
//! ([`BankCache`]): a solve's pilots, attempts, checking runs and output steps build each bank
//! once per step size instead of once per stepper.

use std::sync::{Arc, Mutex, PoisonError};

use super::fused::FusedMaps;
use crate::operator::PhiBank;

/// What a stepper needs for one step size: the kernel bank (nodes c₁..c_s, 1, and 1 + cᵢ with
/// the extrapolating predictor), its combine coefficients and the step as dense maps where the
/// stepper fuses it. Immutable once built, so that steppers share it behind an [`Arc`].
pub(crate) struct Built<Bk> {
    pub(crate) h: f64,
    pub(crate) bank: Bk,
    pub(crate) coef: Vec<f64>,
    pub(crate) fused: Option<FusedMaps>,
}

/// What a bank was built for besides the operator: the step size, the kernel's r and nodes, and
/// whether it holds the predictor's nodes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct BankKey {
    pub(crate) h: u64,
    pub(crate) r: usize,
    pub(crate) nodes: Vec<u64>,
    pub(crate) extrapolate: bool,
    pub(crate) banks: crate::operator::BankArithmetic,
}

impl BankKey {
    pub(crate) fn new(
        h: f64,
        r: usize,
        nodes: &[f64],
        extrapolate: bool,
        banks: crate::operator::BankArithmetic,
    ) -> Self {
        BankKey {
            h: h.to_bits(),
            r,
            nodes: nodes.iter().map(|c| c.to_bits()).collect(),
            extrapolate,
            banks,
        }
    }
}

/// The banks of ONE system's linear operator by step size (and kernel), shared by the steppers
/// that integrate it: a stepper that needs a bank for a step size takes it from here if it was
/// built before and puts it here after building it. It keeps the most recently used banks up to
/// a budget of entries (numbers stored), so that it never holds more than a few banks of a large
/// operator; a bank in use stays alive with its steppers whatever the cache drops.
///
/// A cache must only ever serve steppers of one operator: the key does not identify the
/// operator.
pub(crate) struct BankCache<Bk> {
    inner: Mutex<Inner<Bk>>,
}

struct Inner<Bk> {
    /// Most recently used last.
    entries: Vec<(BankKey, Arc<Built<Bk>>)>,
    /// The most banks kept.
    capacity: usize,
}

impl<Bk: PhiBank> BankCache<Bk> {
    /// A cache keeping up to `capacity` banks.
    pub(crate) fn new(capacity: usize) -> Self {
        BankCache {
            inner: Mutex::new(Inner {
                entries: Vec::new(),
                capacity: capacity.max(1),
            }),
        }
    }

    /// The bank for `key`, built by `build` if it is not here.
    ///
    /// # Errors
    /// What `build` reports (nothing is cached then).
    pub(crate) fn get_or_build<E>(
        &self,
        key: BankKey,
        build: impl FnOnce() -> Result<Built<Bk>, E>,
    ) -> Result<Arc<Built<Bk>>, E> {
        {
            let mut inner = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
            if let Some(i) = inner.entries.iter().position(|(k, _)| *k == key) {
                let entry = inner.entries.remove(i);
                let built = Arc::clone(&entry.1);
                inner.entries.push(entry);
                return Ok(built);
            }
        }
        // Built outside the lock: another stepper may build the same bank meanwhile (the same
        // numbers: building is deterministic); the first one stored is kept.
        let built = Arc::new(build()?);
        let mut inner = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(i) = inner.entries.iter().position(|(k, _)| *k == key) {
            return Ok(Arc::clone(&inner.entries[i].1));
        }
        // A large bank counts as several: the budget is in numbers stored.
        let weight = |b: &Built<Bk>| b.bank.stored();
        inner.entries.push((key, Arc::clone(&built)));
        loop {
            let total: usize = inner.entries.iter().map(|(_, b)| weight(b)).sum();
            if inner.entries.len() <= 1
                || (inner.entries.len() <= inner.capacity && total <= CACHE_BUDGET)
            {
                break;
            }
            inner.entries.remove(0);
        }
        Ok(built)
    }
}

/// The most numbers the banks a cache keeps may hold in all (256 MiB of f64): beyond it the
/// least recently used go first.
pub(crate) const CACHE_BUDGET: usize = 1 << 25;

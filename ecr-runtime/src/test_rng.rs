//! Deterministic pseudo-random numbers for the unit tests (xorshift64, Marsaglia 2003): the
//! same sequence on every machine and run, so that a failing case can be replayed.

/// A xorshift64 generator; its state must not be 0.
pub(crate) struct XorShift(pub(crate) u64);

impl XorShift {
    /// The next state.
    fn advance(&mut self) -> u64 {
        let mut s = self.0;
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        self.0 = s;
        s
    }

    /// Uniform in [0, 1), 53 random bits.
    pub(crate) fn unit(&mut self) -> f64 {
        (self.advance() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// In (−1, 1) times a power of two between `2^−spread` and `2^spread`, both from one
    /// state: numbers of mixed signs and magnitudes, for cancellation in compensated sums.
    pub(crate) fn mixed(&mut self, spread: u32) -> f64 {
        let s = self.advance();
        let unit = (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        unit * f64::powi(2.0, (s % u64::from(2 * spread + 1)) as i32 - spread as i32)
    }
}

//! Monotonic clock: ticks at a fixed rate, and an optional cycle counter.
//!
//! The core never reads a clock; the runner reads this one and passes `now`
//! into the core, so a simulated clock makes whole runs reproducible.

use crate::error::ErrorType;

/// A monotonic tick counter.
pub trait Clock: ErrorType {
    /// Ticks per second of [`Clock::now_ticks`].
    ///
    /// # Contract
    /// * Constant for the lifetime of the clock and never zero.
    fn tick_hz(&self) -> u32;

    /// The current time in ticks since an arbitrary epoch.
    ///
    /// # Contract
    /// * Monotonic: never smaller than a value returned earlier by the same clock.
    /// * Does not block. An error (kind [`Unavailable`](crate::ErrorKind::Unavailable)
    ///   or [`Other`](crate::ErrorKind::Other)) means the time is unknown; the
    ///   runner then stops timing the step instead of guessing.
    fn now_ticks(&mut self) -> Result<u64, Self::Error>;

    /// A free-running CPU cycle counter, if the platform has one.
    ///
    /// # Contract
    /// * `None` when no cycle counter exists (the default); otherwise wraps
    ///   modulo 2⁶⁴ and is only meaningful as a difference of two reads.
    /// * Cycles are reported as cycles, never converted to time here.
    fn cycles(&mut self) -> Option<u64> {
        None
    }
}

impl<T: Clock + ?Sized> Clock for &mut T {
    fn tick_hz(&self) -> u32 {
        T::tick_hz(self)
    }
    fn now_ticks(&mut self) -> Result<u64, Self::Error> {
        T::now_ticks(self)
    }
    fn cycles(&mut self) -> Option<u64> {
        T::cycles(self)
    }
}

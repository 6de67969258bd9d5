//! Optional logging: with the `defmt` feature the macros forward to `defmt`,
//! without it they compile to nothing (arguments are still type-checked).
#![allow(unused_macros)]

macro_rules! log_debug {
    ($($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        ::defmt::debug!($($arg)*);
    }};
}

macro_rules! log_warn {
    ($($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        ::defmt::warn!($($arg)*);
    }};
}

/// `debug_assert!` for internal invariants (never for input, which gets a
/// failure code): with the `defmt` feature through `defmt::debug_assert!`, so the
/// message goes out through the target's logger; otherwise `core::debug_assert!`.
/// Release builds compile it out, so it adds no panic path to a flight image.
macro_rules! invariant {
    ($cond:expr, $msg:literal) => {{
        #[cfg(feature = "defmt")]
        ::defmt::debug_assert!($cond, $msg);
        #[cfg(not(feature = "defmt"))]
        ::core::debug_assert!($cond, $msg);
    }};
}

/// A slice that an internal invariant says exists: debug builds assert it
/// ([`invariant!`]); release builds fall back to the empty slice, so a broken
/// invariant degrades the result instead of panicking.
#[inline]
pub(crate) fn present<T>(slice: Option<&[T]>) -> &[T] {
    invariant!(
        slice.is_some(),
        "slice required by an internal invariant is missing"
    );
    slice.unwrap_or(&[])
}

/// [`present`] for a mutable slice.
#[inline]
pub(crate) fn present_mut<T>(slice: Option<&mut [T]>) -> &mut [T] {
    invariant!(
        slice.is_some(),
        "slice required by an internal invariant is missing"
    );
    slice.unwrap_or(&mut [])
}

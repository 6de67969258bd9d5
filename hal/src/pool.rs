//! Workers for one relocalization's attempts: the engine hands out its
//! attempts as tickets ([`vtsm_core::reloc::Relocalizer::ticket`]), an
//! [`AttemptPool`] runs them on its workers — the host's threads, or a flight
//! integrator's tasks, each with its own pipeline
//! ([`vtsm_core::reloc::Engine::worker`]) and workspace — and hands the work
//! back oldest first, and [`crate::runner::Session::step_pooled`] takes it
//! back in attempt order ([`vtsm_core::reloc::Relocalizer::commit`]).
//!
//! The outcome is bit-identical to [`crate::runner::Session::step`]'s for
//! every number of workers: an attempt depends only on its index and the
//! round's state, and work drawn under a state that no longer holds (the
//! round ended, Focus re-centred it) is dropped ([`AttemptPool::cancel`])
//! and drawn again. What differs is the time, and the work thrown away: at
//! most [`AttemptPool::capacity`] − 1 attempts each time the state changes.
//!
//! Bounds: `capacity` tickets in flight at most; every call of
//! [`AttemptPool::next`] returns the oldest one or `None` when none is in
//! flight, so a step does at most its unit budget of commits.

use vtsm_core::reloc::{Ticket, Worked};

/// Workers that run an engine's attempt tickets.
///
/// # Contract
/// * [`AttemptPool::next`] returns the work of the oldest ticket submitted
///   and not yet returned or cancelled, run with
///   [`vtsm_core::reloc::work_ticket`] on a pipeline of the same engine
///   (blocking until it is done), and `None` when there is none;
/// * [`AttemptPool::cancel`] forgets every ticket in flight: their work,
///   finished or not, is never returned;
/// * `in_flight` counts the tickets submitted and neither returned nor cancelled.
pub trait AttemptPool {
    /// Tickets that may be in flight at once (≥ 1; the number of workers,
    /// or more to keep them busy while the oldest is taken back).
    fn capacity(&self) -> u32;
    /// Tickets in flight.
    fn in_flight(&self) -> u32;
    /// Hand `ticket` to a worker.
    fn submit(&mut self, ticket: Ticket);
    /// The work of the oldest ticket in flight, once done.
    fn next(&mut self) -> Option<Worked>;
    /// Drop every ticket in flight.
    fn cancel(&mut self);
}

//! The host's [`AttemptPool`]: a relocalization's attempts on `K` threads,
//! each with its own pipeline and workspace, taken back in attempt order.
//!
//! Threads live in the caller's [`std::thread::scope`] for one
//! relocalization. Tickets go to whichever thread is free (one shared
//! queue); each worked ticket comes back tagged with the pool's generation,
//! which [`AttemptPool::cancel`] advances, so work drawn before a change of
//! the round's state is dropped wherever it is (a thread skips a queued
//! ticket of an old generation without working it). The outcome is the one
//! of a single thread, bit for bit ([`vtsm_hal::pool`]).

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::Scope;
use vtsm_core::reloc::{work_ticket, Attempt, Ticket, Worked};
use vtsm_hal::AttemptPool;

/// The number of threads a relocalization uses when the caller does not
/// say: rayon's, which honours `RAYON_NUM_THREADS` and is otherwise every
/// core.
pub fn default_threads() -> usize {
    rayon::current_num_threads().max(1)
}

/// Attempt workers on threads of a scope.
pub struct ThreadPool {
    jobs: Option<Sender<(u64, Ticket)>>,
    results: Receiver<(u64, Worked)>,
    generation: Arc<AtomicU64>,
    /// Tickets worked by the threads, stale ones included.
    worked: Arc<AtomicU32>,
    /// Indices of the tickets in flight, oldest first.
    flight: VecDeque<u32>,
    /// Work of this generation that came back before its turn.
    done: HashMap<u32, Worked>,
    capacity: u32,
}

impl ThreadPool {
    /// One thread per pipeline in `workers`, spawned in `scope`; up to two
    /// tickets per thread in flight, so a thread finds the next one queued
    /// while the oldest is taken back.
    pub fn start<'scope, A>(scope: &'scope Scope<'scope, '_>, workers: Vec<A>) -> Self
    where
        A: Attempt + Send + 'scope,
    {
        let (jobs, queue) = channel::<(u64, Ticket)>();
        let (done_tx, results) = channel();
        let queue = Arc::new(Mutex::new(queue));
        let generation = Arc::new(AtomicU64::new(0));
        let worked = Arc::new(AtomicU32::new(0));
        let capacity = u32::try_from(workers.len().saturating_mul(2))
            .unwrap_or(u32::MAX)
            .max(1);
        for mut attempt in workers {
            let queue = Arc::clone(&queue);
            let done_tx = done_tx.clone();
            let generation = Arc::clone(&generation);
            let count = Arc::clone(&worked);
            scope.spawn(move || loop {
                // The lock is held only while waiting for the next ticket.
                let job = match queue.lock() {
                    Ok(q) => q.recv(),
                    Err(_) => break,
                };
                let Ok((g, ticket)) = job else {
                    break;
                };
                if g != generation.load(Ordering::Acquire) {
                    continue;
                }
                let worked = work_ticket(&mut attempt, &ticket);
                count.fetch_add(1, Ordering::Relaxed);
                if done_tx.send((g, worked)).is_err() {
                    break;
                }
            });
        }
        Self {
            jobs: Some(jobs),
            results,
            generation,
            worked,
            flight: VecDeque::new(),
            done: HashMap::new(),
            capacity,
        }
    }

    /// Tickets the threads have worked so far, those dropped as stale
    /// included (the attempts taken back are the engine's count).
    pub fn worked(&self) -> u32 {
        self.worked.load(Ordering::Relaxed)
    }

    fn generation(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }
}

impl Drop for ThreadPool {
    /// Closes the queue: every thread ends after the ticket it is working.
    fn drop(&mut self) {
        self.generation.fetch_add(1, Ordering::AcqRel);
        self.jobs = None;
    }
}

impl AttemptPool for ThreadPool {
    fn capacity(&self) -> u32 {
        self.capacity
    }

    fn in_flight(&self) -> u32 {
        u32::try_from(self.flight.len()).unwrap_or(u32::MAX)
    }

    fn submit(&mut self, ticket: Ticket) {
        let g = self.generation();
        let sent = self.jobs.as_ref().map(|j| j.send((g, ticket)));
        if matches!(sent, Some(Ok(()))) {
            self.flight.push_back(ticket.index());
        }
    }

    fn next(&mut self) -> Option<Worked> {
        let oldest = *self.flight.front()?;
        let g = self.generation();
        loop {
            if let Some(w) = self.done.remove(&oldest) {
                self.flight.pop_front();
                return Some(w);
            }
            match self.results.recv() {
                Ok((wg, w)) if wg == g => {
                    self.done.insert(w.ticket.index(), w);
                }
                Ok(_) => {}
                // Every thread is gone: nothing more comes back; the
                // runner's own pipeline does the rest.
                Err(_) => {
                    self.flight.clear();
                    return None;
                }
            }
        }
    }

    fn cancel(&mut self) {
        if !self.flight.is_empty() || !self.done.is_empty() {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
        self.flight.clear();
        self.done.clear();
    }
}

/// What one attempt did, as [`RecordingPool`] reports it: the index into
/// the mask M̂ of the vertex SamplePoint drew (`None`: none in view) and the
/// attempt's correspondence or the code that rejected it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleRecord {
    /// Index into M̂ ([`vtsm_core::map::MapView::mask_vertex`]).
    pub mask_index: Option<u32>,
    /// The attempt's result.
    pub result: Result<vtsm_core::pose::Correspondence, vtsm_core::FailureCode>,
}

/// One worker on the caller's thread that reports every attempt taken back
/// to `record`, in attempt order: a measurement of which map points match,
/// with the outcome of one thread, bit for bit.
pub struct RecordingPool<'p, 'a, 'w, F> {
    attempt: vtsm_core::reloc::Pipeline<'a, 'w, F>,
    record: &'p mut dyn FnMut(SampleRecord),
    held: Option<(Option<u32>, Worked)>,
}

impl<'p, 'a, 'w, F> RecordingPool<'p, 'a, 'w, F> {
    /// A pool of one over `attempt` (a twin of the engine's pipeline).
    pub fn new(
        attempt: vtsm_core::reloc::Pipeline<'a, 'w, F>,
        record: &'p mut dyn FnMut(SampleRecord),
    ) -> Self {
        Self {
            attempt,
            record,
            held: None,
        }
    }
}

impl<F: vtsm_core::frame::FrameSource> AttemptPool for RecordingPool<'_, '_, '_, F> {
    fn capacity(&self) -> u32 {
        1
    }

    fn in_flight(&self) -> u32 {
        u32::from(self.held.is_some())
    }

    fn submit(&mut self, ticket: Ticket) {
        let worked = work_ticket(&mut self.attempt, &ticket);
        self.held = Some((self.attempt.last_sample(), worked));
    }

    fn next(&mut self) -> Option<Worked> {
        let (mask_index, worked) = self.held.take()?;
        (self.record)(SampleRecord {
            mask_index,
            result: worked.result,
        });
        Some(worked)
    }

    fn cancel(&mut self) {
        self.held = None;
    }
}

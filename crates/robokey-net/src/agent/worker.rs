//! The controller agent's worker thread for block-time computations (docs/protocol.md,
//! "Post-processing between the agents"): the estimate of the plant with slip in it takes
//! seconds, during which the agent's loop must go on answering the robot and noticing its
//! timeouts. The loop hands the worker one job at a time over a bounded channel and polls
//! for the answer; the computation itself is the core's, pure
//! ([`robokey::connection::BlockComputation::run`]), and spreads one block over the worker's
//! own pool of threads (the same result on any number of them).

use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use robokey::connection::{BlockComputation, Computed};

use crate::error::NetError;

/// How often the loop looks for the worker's answer while one is outstanding.
pub(crate) const ANSWER_POLL: Duration = Duration::from_millis(5);

/// An answer, with what was computed and how long it took (wall time).
pub(crate) struct Answered {
    pub(crate) computed: Computed,
    pub(crate) what: &'static str,
    pub(crate) took: Duration,
}

/// The worker thread and its channels.
pub(crate) struct Worker {
    jobs: Option<SyncSender<BlockComputation>>,
    answers: Receiver<Answered>,
    thread: Option<JoinHandle<()>>,
    /// Whether a job is out, its answer not taken yet.
    busy: bool,
}

impl Worker {
    /// Starts the worker thread and its pool of `threads` computing threads (0: one per
    /// core; never more than one per core), both before the session starts, so that a
    /// machine that cannot give them is told at once rather than when the first block is
    /// computed.
    ///
    /// # Errors
    /// The threads cannot be started (the system's thread limit, memory).
    pub(crate) fn start(threads: usize) -> Result<Self, NetError> {
        let cores = std::thread::available_parallelism().map_or(1, usize::from);
        let threads = if threads == 0 {
            cores
        } else {
            threads.min(cores)
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("block-estimate-{i}"))
            .build()
            .map_err(|e| {
                cannot_start(
                    &format!("the block estimate's {threads} threads (--jobs 1: one)"),
                    e,
                )
            })?;
        // One job at a time: the endpoint waits for each answer before it asks again.
        let (jobs, inbox) = sync_channel::<BlockComputation>(1);
        let (outbox, answers) = sync_channel::<Answered>(1);
        let thread = std::thread::Builder::new()
            .name("block-computation".into())
            .spawn(move || {
                for job in inbox {
                    let (what, started) = (job.describe(), Instant::now());
                    let computed = pool.install(|| job.run());
                    let answered = Answered {
                        computed,
                        what,
                        took: started.elapsed(),
                    };
                    if outbox.send(answered).is_err() {
                        // The loop ended: nobody waits for the answer.
                        return;
                    }
                }
            })
            .map_err(|e| cannot_start("the block computation's thread", e))?;
        Ok(Self {
            jobs: Some(jobs),
            answers,
            thread: Some(thread),
            busy: false,
        })
    }

    /// Hands the worker `job`.
    ///
    /// # Errors
    /// The worker has stopped (a computation panicked).
    pub(crate) fn submit(&mut self, job: BlockComputation) -> Result<(), NetError> {
        let sent = self
            .jobs
            .as_ref()
            .is_some_and(|jobs| jobs.send(job).is_ok());
        if !sent {
            return Err(stopped());
        }
        self.busy = true;
        Ok(())
    }

    /// Whether a job is out.
    pub(crate) fn is_busy(&self) -> bool {
        self.busy
    }

    /// The answer, if the job is done.
    ///
    /// # Errors
    /// The worker stopped without answering (a computation panicked).
    pub(crate) fn try_answer(&mut self) -> Result<Option<Answered>, NetError> {
        if !self.busy {
            return Ok(None);
        }
        match self.answers.try_recv() {
            Ok(answered) => {
                self.busy = false;
                Ok(Some(answered))
            }
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => {
                self.busy = false;
                Err(stopped())
            }
        }
    }
}

impl Drop for Worker {
    /// Closes the job channel; an idle worker ends and is joined. A busy one is left to end
    /// on its own once its computation is done: the agent does not wait for an answer it
    /// gave up on.
    fn drop(&mut self) {
        self.jobs = None;
        if !self.busy
            && let Some(thread) = self.thread.take()
        {
            let _ = thread.join();
        }
    }
}

/// The error of threads that could not be started (a runtime failure, exit 1).
fn cannot_start(what: &str, error: impl std::fmt::Display) -> NetError {
    NetError::Io {
        context: format!("cannot start {what}"),
        error: std::io::Error::other(error.to_string()),
    }
}

fn stopped() -> NetError {
    NetError::Usage(
        "the block's computation stopped without an answer (its worker thread panicked): \
         the block in flight is settled in the next session"
            .into(),
    )
}

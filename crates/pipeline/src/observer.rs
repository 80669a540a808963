//! How a stage tells its caller what it is doing: one [`Observer`] receives [`Event`]s. The CLI draws them as
//! progress bars; a binding forwards them to a callback; [`Quiet`] drops them. A stage never prints.

use std::sync::atomic::{AtomicU64, Ordering};

/// What a stage reports while it runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Event<'a> {
    /// A piece of work begins: `steps` of it (0 while not yet known). `task` numbers it within the process.
    Started { task: u64, what: &'a str, steps: u64 },
    /// `done` of `steps` are done (`steps` may grow as the work finds more).
    Progress { task: u64, done: u64, steps: u64 },
    /// What the task is doing now (a training's loss, a merge's stage).
    Status { task: u64, text: &'a str },
    /// The task ended.
    Finished { task: u64 },
    /// A line worth a user's eyes (a demo stage's command line, a stage skipped): the CLI prints it.
    Note(&'a str),
}

/// Receives the events of a running stage. `Sync`: a stage may report from its worker threads.
pub trait Observer: Sync {
    fn event(&self, event: Event<'_>);
}

/// Drops every event.
pub struct Quiet;

impl Observer for Quiet {
    fn event(&self, _: Event<'_>) {}
}

impl<F: Fn(Event<'_>) + Sync> Observer for F {
    fn event(&self, event: Event<'_>) {
        self(event)
    }
}

static NEXT_TASK: AtomicU64 = AtomicU64::new(0);

/// A task being reported to an observer: counts its steps and says when it ends (also when dropped).
pub struct Task<'o> {
    observer: &'o dyn Observer,
    id: u64,
    done: AtomicU64,
    steps: AtomicU64,
    finished: std::sync::atomic::AtomicBool,
}

impl<'o> Task<'o> {
    /// Starts a task of `steps` steps (0: not yet known).
    pub fn start(observer: &'o dyn Observer, what: &str, steps: u64) -> Task<'o> {
        let id = NEXT_TASK.fetch_add(1, Ordering::Relaxed);
        observer.event(Event::Started { task: id, what, steps });
        Task {
            observer,
            id,
            done: AtomicU64::new(0),
            steps: AtomicU64::new(steps),
            finished: Default::default(),
        }
    }

    fn report(&self) {
        self.observer.event(Event::Progress {
            task: self.id,
            done: self.done.load(Ordering::Relaxed),
            steps: self.steps.load(Ordering::Relaxed),
        });
    }

    /// `n` more steps done.
    pub fn inc(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
        self.report();
    }

    /// The task now has `steps` steps in all.
    pub fn set_length(&self, steps: u64) {
        self.steps.store(steps, Ordering::Relaxed);
        self.report();
    }

    /// `done` steps are done.
    pub fn set_position(&self, done: u64) {
        self.done.store(done, Ordering::Relaxed);
        self.report();
    }

    /// Steps done so far.
    pub fn position(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }

    /// What the task is doing now.
    pub fn set_status(&self, text: &str) {
        self.observer.event(Event::Status { task: self.id, text });
    }

    /// A library's progress callback `(done, all)`, the total known only once the work starts.
    pub fn follow(&self) -> impl Fn(usize, usize) + Sync + '_ {
        move |done, all| {
            self.steps.store(all as u64, Ordering::Relaxed);
            self.set_position(done as u64);
        }
    }

    /// The task ended.
    pub fn finish(&self) {
        if !self.finished.swap(true, Ordering::Relaxed) {
            self.observer.event(Event::Finished { task: self.id });
        }
    }
}

impl Drop for Task<'_> {
    fn drop(&mut self) {
        self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn a_task_reports_its_steps_and_ends_once() {
        let seen = Mutex::new(Vec::new());
        let observer = |e: Event<'_>| {
            let line = match e {
                Event::Started { what, steps, .. } => format!("start {what} {steps}"),
                Event::Progress { done, steps, .. } => format!("{done}/{steps}"),
                Event::Status { text, .. } => format!("status {text}"),
                Event::Finished { .. } => "end".into(),
                Event::Note(n) => format!("note {n}"),
            };
            seen.lock().unwrap().push(line);
        };
        {
            let task = Task::start(&observer, "GA", 2);
            task.inc(1);
            task.set_length(3);
            task.follow()(3, 4);
            task.set_status("frame 3");
            task.finish();
        }
        assert_eq!(
            *seen.lock().unwrap(),
            ["start GA 2", "1/2", "1/3", "3/4", "status frame 3", "end"]
        );
    }
}

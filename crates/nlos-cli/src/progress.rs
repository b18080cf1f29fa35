//! Progress of the steps that can take more than a few seconds, on stderr: a bar (or a spinner, where the
//! amount of work is not known) on a terminal; where stderr is a file or a pipe, a line when the step has run
//! for a second, one every few seconds while it runs, and one when it ends, so that a log shows what is
//! running. A step that ends within the first second shows nothing (its error, if any, is the first line).
//! `NLOS_PROGRESS_DELAY_MS` sets that second (0: every step shows).

use std::io::IsTerminal;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Seconds between two lines of a step that runs in a log.
const LINE_EVERY: Duration = Duration::from_secs(5);

/// How often the display reads the counter.
const POLL: Duration = Duration::from_millis(100);

/// How long a step runs before it shows: `NLOS_PROGRESS_DELAY_MS`, or one second.
fn delay() -> Duration {
    let ms = std::env::var("NLOS_PROGRESS_DELAY_MS").ok().and_then(|v| v.parse().ok()).unwrap_or(1000);
    Duration::from_millis(ms)
}

/// One step on show until [`Step::finish`] (or drop): `what` with the counter's count of `total` (no count
/// where `total` is 0).
#[derive(Debug)]
pub(crate) struct Step {
    stop: Arc<AtomicBool>,
    /// Set by [`Step::finish`]: the step ended well (a log gets its "done" line; a failed step's error says
    /// the rest).
    ok: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Step {
    /// Shows a step without a count (a spinner; its start and end in a log).
    pub(crate) fn spinner(what: impl Into<String>) -> Self {
        Self::counted(what, Arc::new(AtomicUsize::new(0)), 0)
    }

    /// Shows `counter` out of `total` for the step `what`.
    pub(crate) fn counted(what: impl Into<String>, counter: Arc<AtomicUsize>, total: usize) -> Self {
        let what = what.into();
        let stop = Arc::new(AtomicBool::new(false));
        let ok = Arc::new(AtomicBool::new(false));
        let (flag, ended_well) = (Arc::clone(&stop), Arc::clone(&ok));
        let terminal = std::io::stderr().is_terminal();
        let (start, delay) = (Instant::now(), delay());
        // Without a delay the first line is written before the step starts, whatever the thread's timing.
        let shown_now = delay.is_zero() && !terminal;
        if shown_now {
            eprintln!("{what}…");
        }
        let thread = std::thread::spawn(move || {
            // Shown once the step has run `delay`: a bar, or its first line.
            let mut bar: Option<indicatif::ProgressBar> = None;
            let mut shown = shown_now;
            let mut next_line = start + delay + LINE_EVERY;
            loop {
                let stopped = flag.load(Ordering::Relaxed);
                let done = counter.load(Ordering::Relaxed).min(total);
                if !shown && !stopped && start.elapsed() >= delay {
                    shown = true;
                    if terminal {
                        bar = Some(self::bar(&what, total));
                    } else {
                        eprintln!("{what}…");
                    }
                }
                if stopped {
                    break;
                }
                match &bar {
                    Some(bar) => bar.set_position(done as u64),
                    None if shown && Instant::now() >= next_line => {
                        next_line += LINE_EVERY;
                        eprintln!("{what}: {}, {} s", amount(done, total), start.elapsed().as_secs());
                    }
                    None => {}
                }
                let until_shown = delay.saturating_sub(start.elapsed());
                std::thread::sleep(if shown || until_shown.is_zero() { POLL } else { until_shown.min(POLL) });
            }
            match bar {
                Some(bar) => bar.finish_and_clear(),
                None if shown && ended_well.load(Ordering::Relaxed) => {
                    eprintln!("{what}: done in {:.1} s", start.elapsed().as_secs_f64());
                }
                None => {}
            }
        });
        Self { stop, ok, thread: Some(thread) }
    }

    /// Ends the step's display (its last line in a log).
    pub(crate) fn finish(mut self) {
        self.ok.store(true, Ordering::Relaxed);
        self.end();
    }

    fn end(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Step {
    fn drop(&mut self) {
        self.end();
    }
}

/// `37 % (1520 of 4096)`, or `running` without a total.
fn amount(done: usize, total: usize) -> String {
    match (100 * done).checked_div(total) {
        Some(percent) => format!("{percent} % ({done} of {total})"),
        None => "running".into(),
    }
}

fn bar(what: &str, total: usize) -> indicatif::ProgressBar {
    let (bar, template) = if total == 0 {
        (indicatif::ProgressBar::new_spinner(), "{spinner} {msg} · {elapsed}")
    } else {
        (indicatif::ProgressBar::new(total as u64), "{msg} [{bar:30}] {pos}/{len} · {elapsed} · ETA {eta}")
    };
    let style = indicatif::ProgressStyle::with_template(template)
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(what.to_owned());
    bar.enable_steady_tick(POLL);
    bar
}

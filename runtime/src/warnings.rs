//! The process's own warnings and errors, kept for whoever shows them
//! beside the log file: the central unit's Foxglove server puts them on its
//! log panel. [`init_tracing`](crate::init_tracing) installs the
//! [`WarningTap`] layer; [`drain`] takes what came since the last call.
//!
//! At most [`KEPT`] lines wait: a process nobody drains keeps its newest
//! lines and counts the ones it let go, so the tap costs a bounded amount
//! of memory whether or not anyone looks.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::sync::Mutex;

use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, Layer};

/// Lines kept until drained.
pub const KEPT: usize = 256;

/// One warning or error of the process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Warning {
    /// `WARN` or `ERROR`.
    pub level: Level,
    /// The module that logged it (the `tracing` target).
    pub target: String,
    /// The message with its fields, as the log file has it.
    pub message: String,
    /// When it was logged, nanoseconds since the Unix epoch.
    pub at_ns: u64,
}

/// Lines waiting, and how many were let go since the last drain.
static WAITING: Mutex<(VecDeque<Warning>, u64)> = Mutex::new((VecDeque::new(), 0));

/// The `tracing` layer that keeps every warning and error (see the module doc).
#[derive(Debug, Default, Clone, Copy)]
pub struct WarningTap;

impl<S: Subscriber> Layer<S> for WarningTap {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let level = *event.metadata().level();
        if level > Level::WARN {
            return;
        }
        let mut text = MessageText::default();
        event.record(&mut text);
        keep(Warning {
            level,
            target: event.metadata().target().to_string(),
            message: text.0,
            at_ns: crate::system_now().as_nanos().max(0) as u64,
        });
    }
}

fn keep(w: Warning) {
    let Ok(mut waiting) = WAITING.lock() else {
        return;
    };
    if waiting.0.len() >= KEPT {
        waiting.0.pop_front();
        waiting.1 += 1;
    }
    waiting.0.push_back(w);
}

/// The warnings and errors logged since the last call, oldest first, and
/// how many older ones were let go meanwhile.
pub fn drain() -> (Vec<Warning>, u64) {
    let Ok(mut waiting) = WAITING.lock() else {
        return (Vec::new(), 0);
    };
    let lost = std::mem::take(&mut waiting.1);
    (waiting.0.drain(..).collect(), lost)
}

/// The message and the other fields of an event, `message k=v ...`.
#[derive(Default)]
struct MessageText(String);

impl Visit for MessageText {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        } else {
            let sep = if self.0.is_empty() { "" } else { " " };
            let _ = write!(self.0, "{sep}{}={value:?}", field.name());
        }
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.0.push_str(value);
        } else {
            self.record_debug(field, &value);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tracing_subscriber::layer::SubscriberExt;

    #[test]
    fn warnings_and_errors_are_kept_bounded_and_information_is_not() {
        let subscriber = tracing_subscriber::registry().with(WarningTap);
        tracing::subscriber::with_default(subscriber, || {
            let _ = drain();
            tracing::info!("an ordinary line");
            tracing::warn!(cell = "c2", "cell down");
            tracing::error!("disk full");
            let (lines, lost) = drain();
            assert_eq!(lost, 0);
            assert_eq!(lines.len(), 2, "{lines:?}");
            assert_eq!(lines[0].level, Level::WARN);
            assert_eq!(lines[0].message, "cell down cell=\"c2\"");
            assert_eq!(lines[1].level, Level::ERROR);
            assert_eq!(lines[1].message, "disk full");
            assert!(drain().0.is_empty(), "drained once");
            for k in 0..KEPT + 10 {
                tracing::warn!("flood {k}");
            }
            let (lines, lost) = drain();
            assert_eq!(lines.len(), KEPT);
            assert_eq!(lost, 10);
            assert_eq!(lines[0].message, "flood 10", "the newest are kept");
        });
    }
}

//! When a shot must be abandoned (design.md section 2's loop, beyond the
//! paper, whose solves ran to the end): a deadline (`--time-limit`) or a
//! raised flag (Ctrl-C, a live view's stop button), checked within a shot
//! so even a long shot of a large scene ends promptly.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::StopReason;

/// When a shot must be abandoned: a deadline, a raised flag.
#[derive(Clone, Debug, Default)]
pub struct Abort {
    pub(super) deadline: Option<Instant>,
    pub(super) flag: Option<Arc<AtomicBool>>,
}

impl Abort {
    /// Why to stop now, if so.
    pub fn reason(&self) -> Option<StopReason> {
        if self
            .flag
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
        {
            return Some(StopReason::Stopped);
        }
        if self.deadline.is_some_and(|d| Instant::now() >= d) {
            return Some(StopReason::TimeLimit);
        }
        None
    }

    /// True when the shot must be abandoned.
    pub fn fired(&self) -> bool {
        self.reason().is_some()
    }

    /// Moves the deadline (if any) `by` later: time that is not the
    /// solve's own.
    pub(super) fn postpone(&mut self, by: Duration) {
        if let Some(deadline) = &mut self.deadline {
            *deadline += by;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deadline passed fires; postponed by time that was not the solve's
    /// own (a pause), it no longer does; an interrupt fires whatever the
    /// deadline.
    #[test]
    fn a_postponed_deadline_leaves_out_the_time_given_back() {
        let mut abort = Abort {
            deadline: Some(Instant::now()),
            flag: None,
        };
        assert_eq!(abort.reason(), Some(StopReason::TimeLimit));
        abort.postpone(Duration::from_secs(3600));
        assert_eq!(abort.reason(), None);
        let flag = Arc::new(AtomicBool::new(true));
        abort.flag = Some(flag);
        assert_eq!(abort.reason(), Some(StopReason::Stopped));
        let mut unlimited = Abort::default();
        unlimited.postpone(Duration::from_secs(1));
        assert_eq!(unlimited.reason(), None);
    }
}

//! Profile-counter continuity over a stream of returns: the counter range, forward jumps by
//! more than one profile (lost profiles) and decreases (a counter wrap or a reordered file).
//! A stream may be tracked in consecutive segments (e.g. chunks processed in parallel) and the
//! segments' trackers appended in order: the result equals tracking the whole stream at once.

use serde::Serialize;

/// At most this many jumps and decreases are listed (all are counted).
pub const MAX_LISTED_JUMPS: usize = 10;

/// A change of the profile counter other than by 0 or +1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct CounterJump {
    /// Where the new value appears: 1-based line (CSV) or 0-based record (binary).
    pub at: u64,
    /// Counter before the jump.
    pub from: u32,
    /// Counter after the jump.
    pub to: u32,
}

/// What one counter value did to the stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CounterStep {
    /// The first value, the same profile or the next one.
    Continues,
    /// A forward jump by more than one profile.
    Jump,
    /// The counter went down.
    Decrease,
}

/// Running summary of a stream of profile counters.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CounterTracker {
    /// Position of the first value (as given to [`Self::add`]).
    #[serde(skip)]
    first_at: u64,
    /// First counter.
    pub first_profile: Option<u32>,
    /// Last counter.
    pub last_profile: Option<u32>,
    /// Distinct profiles (counter changes + 1).
    pub profiles: u64,
    /// Forward jumps by more than one profile (all counted).
    pub jump_count: u64,
    /// Decreases of the counter (wraps or reordering; all counted).
    pub wrap_count: u64,
    /// The first decrease.
    #[serde(skip)]
    pub first_decrease: Option<CounterJump>,
    /// The first [`MAX_LISTED_JUMPS`] forward jumps and decreases, in stream order.
    pub jumps: Vec<CounterJump>,
}

impl CounterTracker {
    /// Adds the counter of the return at `at` (1-based line or 0-based record).
    #[inline]
    pub fn add(&mut self, at: u64, profile: u32) -> CounterStep {
        let Some(prev) = self.last_profile else {
            (self.first_at, self.first_profile, self.last_profile) =
                (at, Some(profile), Some(profile));
            self.profiles = 1;
            return CounterStep::Continues;
        };
        self.last_profile = Some(profile);
        if profile == prev {
            return CounterStep::Continues;
        }
        self.profiles += 1;
        if profile == prev + 1 {
            return CounterStep::Continues;
        }
        let jump = CounterJump {
            at,
            from: prev,
            to: profile,
        };
        let step = if profile < prev {
            self.wrap_count += 1;
            self.first_decrease.get_or_insert(jump);
            CounterStep::Decrease
        } else {
            self.jump_count += 1;
            CounterStep::Jump
        };
        self.list(jump);
        step
    }

    fn list(&mut self, jump: CounterJump) {
        if self.jumps.len() < MAX_LISTED_JUMPS {
            self.jumps.push(jump);
        }
    }

    /// Appends the tracker of the segment that follows this one's.
    pub fn append(&mut self, later: &CounterTracker) {
        let (Some(first), Some(last)) = (later.first_profile, later.last_profile) else {
            return;
        };
        if self.last_profile.is_none() {
            *self = later.clone();
            return;
        }
        // The boundary: the later segment's first value after this one's last (counted here
        // as a new profile when it is one, so not again below).
        self.add(later.first_at, first);
        self.last_profile = Some(last);
        self.profiles += later.profiles - 1;
        self.jump_count += later.jump_count;
        self.wrap_count += later.wrap_count;
        if self.first_decrease.is_none() {
            self.first_decrease = later.first_decrease;
        }
        for j in &later.jumps {
            self.list(*j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(values: &[(u64, u32)]) -> CounterTracker {
        let mut t = CounterTracker::default();
        for &(at, p) in values {
            t.add(at, p);
        }
        t
    }

    #[test]
    fn segments_appended_equal_the_whole_stream() {
        let stream: Vec<(u64, u32)> = [5, 5, 6, 9, 9, 10, 4, 4, 5, 20, 21, 21, 30]
            .iter()
            .enumerate()
            .map(|(i, &p)| (i as u64, p))
            .collect();
        let whole = track(&stream);
        assert_eq!(
            (whole.first_profile, whole.last_profile),
            (Some(5), Some(30))
        );
        assert_eq!((whole.jump_count, whole.wrap_count), (3, 1));
        assert_eq!(whole.profiles, 9);
        assert_eq!(
            whole.first_decrease,
            Some(CounterJump {
                at: 6,
                from: 10,
                to: 4
            })
        );
        for cut_a in 0..stream.len() {
            for cut_b in cut_a..stream.len() {
                let mut t = track(&stream[..cut_a]);
                t.append(&track(&stream[cut_a..cut_b]));
                t.append(&track(&stream[cut_b..]));
                assert_eq!(t, whole, "cuts at {cut_a}, {cut_b}");
            }
        }
    }

    #[test]
    fn lists_at_most_ten() {
        let stream: Vec<(u64, u32)> = (0..50).map(|i| (i, i as u32 * 2)).collect();
        let t = track(&stream);
        assert_eq!(t.jump_count, 49);
        assert_eq!(t.jumps.len(), MAX_LISTED_JUMPS);
        assert_eq!(
            t.jumps[0],
            CounterJump {
                at: 1,
                from: 0,
                to: 2
            }
        );
    }
}

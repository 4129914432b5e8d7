//! The fleet check's reference, gathered and sorted once and read for
//! every robot: the median and the median absolute deviation of the
//! recent misfits of every robot but the one judged.
//!
//! Gathering every other robot's held misfits for each fix, as the check
//! is defined, costs the whole fleet's windows per fix: at a thousand
//! robots that was most of the central unit's time. Instead the held
//! misfits of every robot not quarantined are gathered and sorted at once
//! ([`Reference::rebuild`]), remembering what each robot gave, and a
//! robot's reference is that sorted list without its own share: its median
//! and deviation are found by binary searches on the list, in time
//! logarithmic in the fleet, and equal to the median and deviation of the
//! list with the robot's share taken out.
//!
//! The list is gathered again once an eighth as many fixes as it holds have
//! been offered since (at every fix while a fleet holds fewer than eight),
//! when a robot is quarantined or released, or [`REBUILD_S`] after it was
//! gathered: a robot is judged on a reference at most that old, which for
//! a fleet's noise, over windows of two seconds and a reference kept
//! [`super::REFERENCE_AGE_S`], changes nothing it decides.

use std::cmp::Ordering;

use ickon_proto::time::Time;

/// The reference is gathered again at least this often, seconds.
pub const REBUILD_S: f64 = 1.0;

/// The reference is gathered again once the fixes offered since it was
/// gathered reach this fraction of those it holds (as its reciprocal).
const REBUILD_SHARE: usize = 8;

/// The misfits of every robot not quarantined, sorted.
#[derive(Debug, Clone, Default)]
pub(super) struct Reference {
    sorted: Vec<f64>,
    built_at: Option<Time>,
    offered_since: usize,
    stale: bool,
}

/// The centre and spread of a reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Spread {
    /// Misfits in it.
    pub count: usize,
    /// Their median, metres.
    pub centre_m: f64,
    /// Their median absolute deviation from it, metres.
    pub mad_m: f64,
}

impl Reference {
    /// Whether it must be gathered again before a fix offered at `now`.
    pub fn is_due(&self, now: Time) -> bool {
        let Some(built_at) = self.built_at else {
            return true;
        };
        self.stale
            || (now - built_at).as_secs_f64().abs() > REBUILD_S
            || self.offered_since * REBUILD_SHARE >= self.sorted.len().max(1)
    }

    /// Counts a fix offered since it was gathered.
    pub fn offered(&mut self) {
        self.offered_since += 1;
    }

    /// Marks it to be gathered again before the next fix: a robot's
    /// standing changed what it holds.
    pub fn mark_stale(&mut self) {
        self.stale = true;
    }

    /// Gathers it from `shares`, each robot's recent misfits (already
    /// sorted by [`sort_share`]), at `now`.
    pub fn rebuild<'a>(&mut self, shares: impl Iterator<Item = &'a [f64]>, now: Time) {
        self.sorted.clear();
        for share in shares {
            self.sorted.extend_from_slice(share);
        }
        self.sorted.sort_unstable_by(f64::total_cmp);
        self.built_at = Some(now);
        self.offered_since = 0;
        self.stale = false;
    }

    /// Its misfits without `own` (sorted, and all in it: a robot's share as
    /// last gathered).
    pub fn without(&self, own: &[f64]) -> Spread {
        let others = Others {
            all: &self.sorted,
            own,
        };
        let count = self.sorted.len().saturating_sub(own.len());
        if count == 0 {
            return Spread {
                count,
                centre_m: 0.0,
                mad_m: 0.0,
            };
        }
        let centre_m = middle(count, |k| others.nth(k));
        let mad_m = middle(count, |k| others.nth_deviation(centre_m, k));
        Spread {
            count,
            centre_m,
            mad_m,
        }
    }
}

/// Sorts a robot's share as the reference expects it.
pub(super) fn sort_share(share: &mut [f64]) {
    share.sort_unstable_by(f64::total_cmp);
}

/// The median of `count` values from the `k`-th smallest: the middle one,
/// or the mean of the two middle ones for an even count.
fn middle(count: usize, nth: impl Fn(usize) -> f64) -> f64 {
    if count % 2 == 1 {
        nth(count / 2)
    } else {
        0.5 * (nth(count / 2 - 1) + nth(count / 2))
    }
}

/// A sorted list without a sorted sub-list of it.
struct Others<'a> {
    all: &'a [f64],
    own: &'a [f64],
}

fn at_most(v: f64) -> impl Fn(&f64) -> bool {
    move |x| x.total_cmp(&v) != Ordering::Greater
}

/// The first index in `0..n` where `pred` holds (`n` if none), for a
/// `pred` false then true along the indices.
fn first_true(n: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

impl Others<'_> {
    /// How many of the others are at most `v`.
    fn count_at_most(&self, v: f64) -> usize {
        self.all.partition_point(at_most(v)) - self.own.partition_point(at_most(v))
    }

    /// The `k`-th smallest of the others (from 0; `k` below their count):
    /// the least value of the list with more than `k` others at most it.
    fn nth(&self, k: usize) -> f64 {
        let i = first_true(self.all.len(), |i| self.count_at_most(self.all[i]) > k);
        self.all[i.min(self.all.len() - 1)]
    }

    /// How many of the others lie within `d` of `centre` (`|x - centre| <=
    /// d`, as computed): those above the centre by their distance, those
    /// below by theirs, each monotonic along the sorted list.
    fn count_within(&self, centre: f64, d: f64) -> usize {
        within(self.all, centre, d) - within(self.own, centre, d)
    }

    /// The `k`-th smallest distance of the others from `centre`: the least
    /// distance of a value of the list, above or below the centre, with
    /// more than `k` others within it.
    fn nth_deviation(&self, centre: f64, k: usize) -> f64 {
        let split = self.all.partition_point(|x| *x < centre);
        let (below, above) = self.all.split_at(split);
        let enough = |d: f64| self.count_within(centre, d) > k;
        let up = first_true(above.len(), |j| enough(above[j] - centre));
        // Below the centre the distance grows toward the list's start.
        let down = first_true(below.len(), |j| enough(centre - below[below.len() - 1 - j]));
        let up_d = above.get(up).map(|x| x - centre);
        let down_d = below.len().checked_sub(down + 1).map(|i| centre - below[i]);
        match (up_d, down_d) {
            (Some(u), Some(d)) => u.min(d),
            (Some(u), None) => u,
            (None, Some(d)) => d,
            (None, None) => 0.0,
        }
    }
}

/// How many of the sorted `values` lie within `d` of `centre`.
fn within(values: &[f64], centre: f64, d: f64) -> usize {
    let split = values.partition_point(|x| *x < centre);
    let (below, above) = values.split_at(split);
    let up = above.partition_point(|x| x - centre <= d);
    let down = below.len() - below.partition_point(|x| centre - x > d);
    up + down
}

#[cfg(test)]
mod tests;

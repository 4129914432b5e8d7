//! A page of the fleet's robots: of one state or all, by id or nearest
//! first to a place, with the whole fleet's counts by state. Pure: the
//! central unit's `robots` answer and the web API's `/api/robots` page the
//! same way. One pass over the fleet and one sort of the robots matching:
//! the fleet's size, never its square.

use std::cmp::Ordering;

use ickon_proto::msg::admin::{RobotCounts, RobotHealth, RobotPage, RobotsRequest};

/// The fleet's counts by state, how many have a pose, and the `n` worst
/// robots (down, then stale, then the fewest fixes a second, then by id),
/// listed in id order. One pass and one partial selection: the fleet's
/// size, whatever `n`.
pub fn worst(
    robots: impl IntoIterator<Item = RobotHealth>,
    n: usize,
) -> (Vec<RobotHealth>, RobotCounts, u64) {
    let mut counts = RobotCounts::default();
    let mut posed = 0;
    let all: Vec<RobotHealth> = robots
        .into_iter()
        .inspect(|h| {
            count(&mut counts, h);
            posed += u64::from(h.pose_valid);
        })
        .collect();
    let mut kept = all;
    if kept.len() > n {
        if n == 0 {
            kept.clear();
        } else {
            kept.select_nth_unstable_by(n - 1, worse_first);
            kept.truncate(n);
        }
    }
    kept.sort_unstable_by(|a, b| a.id.cmp(&b.id));
    (kept, counts, posed)
}

/// Orders the worse of two robots first: down, then stale, then the
/// fewer fixes a second, then the smaller id.
fn worse_first(a: &RobotHealth, b: &RobotHealth) -> Ordering {
    let rank = |h: &RobotHealth| match h.state() {
        "down" => 0,
        "stale" => 1,
        _ => 2,
    };
    rank(a)
        .cmp(&rank(b))
        .then(a.fixes_per_s.total_cmp(&b.fixes_per_s))
        .then_with(|| a.id.cmp(&b.id))
}

/// Counts `h` in its state.
fn count(counts: &mut RobotCounts, h: &RobotHealth) {
    match h.state() {
        "down" => counts.down += 1,
        "stale" => counts.stale += 1,
        _ => counts.up += 1,
    }
}

/// The page `request` asks of `robots` (in id order); a negative page,
/// one beyond the last, or an unknown state is refused with the reason
/// (and the counts still given).
pub fn page(robots: impl IntoIterator<Item = RobotHealth>, request: &RobotsRequest) -> RobotPage {
    let mut counts = RobotCounts::default();
    let mut matching: Vec<RobotHealth> = Vec::new();
    for h in robots {
        count(&mut counts, &h);
        if request.state.is_empty() || request.state == h.state() {
            matching.push(h);
        }
    }
    let refused = |error: String| RobotPage {
        error,
        page: request.page,
        pages: 1,
        matching: 0,
        counts,
        robots: Vec::new(),
    };
    if let Some(problem) = request.problem() {
        return refused(problem);
    }
    let size = u64::from(request.page_size);
    let total = matching.len() as u64;
    let pages = total.div_ceil(size).max(1);
    let page = u64::try_from(request.page).unwrap_or(u64::MAX);
    if page >= pages {
        return refused(format!(
            "page {} is beyond the last, {} ({total} robots, {size} a page)",
            request.page,
            pages - 1
        ));
    }
    if request.near {
        let (x, y) = (request.near_x_m, request.near_y_m);
        let d2 = |h: &RobotHealth| {
            if h.pose_valid && h.x_m.is_finite() && h.y_m.is_finite() {
                (h.x_m - x).powi(2) + (h.y_m - y).powi(2)
            } else {
                f64::INFINITY
            }
        };
        matching.sort_by(|a, b| d2(a).total_cmp(&d2(b)).then_with(|| a.id.cmp(&b.id)));
    }
    // `page < pages`, and `pages * size` covers `total`: both in range.
    let start = (page * size) as usize;
    let end = (start + size as usize).min(matching.len());
    RobotPage {
        error: String::new(),
        page: request.page,
        pages,
        matching: total,
        counts,
        robots: matching.drain(start..end).collect(),
    }
}

#[cfg(test)]
mod tests;

//! A page of the fleet's robots: of one state or all, by id or nearest
//! first to a place, with the whole fleet's counts by state. Pure: the
//! central unit's `robots` answer and the web API's `/api/robots` page the
//! same way. One pass over the fleet and one sort of the robots matching:
//! the fleet's size, never its square.

use ickon_proto::msg::admin::{RobotCounts, RobotHealth, RobotPage, RobotsRequest};

/// The page `request` asks of `robots` (in id order); a negative page,
/// one beyond the last, or an unknown state is refused with the reason
/// (and the counts still given).
pub fn page(robots: impl IntoIterator<Item = RobotHealth>, request: &RobotsRequest) -> RobotPage {
    let mut counts = RobotCounts::default();
    let mut matching: Vec<RobotHealth> = Vec::new();
    for h in robots {
        match h.state() {
            "down" => counts.down += 1,
            "stale" => counts.stale += 1,
            _ => counts.up += 1,
        }
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

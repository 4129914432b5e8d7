//! The offset between the truth's clock and the measurements' when the
//! files say they are on different clocks: the shift, within
//! [`MAX_OFFSET_S`], that brings the per-epoch least-squares fixes nearest
//! to the truth (median error, robust to the fixes that are wrong).

/// The largest offset searched, seconds.
pub const MAX_OFFSET_S: f64 = 2.0;
/// Seconds of fixes the search uses, from the first: enough motion to
/// tell shifts apart, a bounded share of a long file.
pub const SEARCH_SPAN_S: f64 = 120.0;
/// Coarse then fine steps, seconds.
const COARSE_S: f64 = 0.01;
const FINE_S: f64 = 0.0005;

/// The estimate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Offset {
    /// Measurements' clock minus the truth's, seconds.
    pub offset_s: f64,
    /// Median error of the fixes at that offset, metres.
    pub median_error_m: f64,
    /// Fixes it used.
    pub fixes: usize,
}

/// The offset that minimises the median error between `fixes`
/// (`(t_s, position_m)` on the measurements' clock) and `truth` (in time
/// order, on its own clock); `None` when no shift within the range puts a
/// fix inside the truth.
pub fn estimate(fixes: &[(f64, [f64; 3])], truth: &[(f64, [f64; 3])]) -> Option<Offset> {
    let median_at = |offset: f64| median_error(fixes, truth, offset);
    let steps = (MAX_OFFSET_S / COARSE_S).round() as i64;
    let mut best: Option<(f64, f64, usize)> = None;
    for k in -steps..=steps {
        let o = k as f64 * COARSE_S;
        if let Some((m, n)) = median_at(o)
            && best.is_none_or(|b| m < b.1)
        {
            best = Some((o, m, n));
        }
    }
    let (coarse, _, _) = best?;
    let fine = (COARSE_S / FINE_S).round() as i64;
    for k in -fine..=fine {
        let o = (coarse + k as f64 * FINE_S).clamp(-MAX_OFFSET_S, MAX_OFFSET_S);
        if let Some((m, n)) = median_at(o)
            && best.is_none_or(|b| m < b.1)
        {
            best = Some((o, m, n));
        }
    }
    best.map(|(offset_s, median_error_m, fixes)| Offset {
        offset_s,
        median_error_m,
        fixes,
    })
}

/// The median error and the number of fixes with truth around them; a
/// shift must cover at least half the fixes to count (a shift that keeps
/// only a few lucky fixes is not an answer).
fn median_error(
    fixes: &[(f64, [f64; 3])],
    truth: &[(f64, [f64; 3])],
    offset: f64,
) -> Option<(f64, usize)> {
    let mut errors: Vec<f64> = fixes
        .iter()
        .filter_map(|(t, p)| {
            let q = interpolate(truth, t - offset)?;
            Some((0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
        })
        .collect();
    if errors.is_empty() || 2 * errors.len() < fixes.len() {
        return None;
    }
    let n = errors.len();
    let (_, m, _) = errors.select_nth_unstable_by(n / 2, f64::total_cmp);
    Some((*m, n))
}

fn interpolate(truth: &[(f64, [f64; 3])], t: f64) -> Option<[f64; 3]> {
    let i = truth.partition_point(|r| r.0 <= t);
    if i == 0 {
        return None;
    }
    let (t0, p0) = truth[i - 1];
    if t0 == t {
        return Some(p0);
    }
    let (t1, p1) = *truth.get(i)?;
    let w = (t - t0) / (t1 - t0);
    Some(std::array::from_fn(|k| p0[k] + w * (p1[k] - p0[k])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_known_shift_is_found_from_noisy_fixes() {
        let truth: Vec<(f64, [f64; 3])> = (0..3000)
            .map(|k| {
                let t = f64::from(k) * 0.01;
                (t, [t.sin() * 3.0, (0.7 * t).cos() * 2.0, 0.0])
            })
            .collect();
        let shift = 0.73;
        let fixes: Vec<(f64, [f64; 3])> = (0..250)
            .map(|k| {
                let t = 1.0 + f64::from(k) * 0.1;
                let noise = if k % 7 == 0 { 1.0 } else { 0.01 };
                let s = t - shift;
                (t, [s.sin() * 3.0 + noise, (0.7 * s).cos() * 2.0, 0.0])
            })
            .collect();
        let o = estimate(&fixes, &truth).unwrap();
        assert!((o.offset_s - shift).abs() < 0.002, "{o:?}");
    }
}

use super::*;

/// The median of `values` by sorting them: the definition the searches
/// must match exactly.
fn sorted_median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// A small deterministic generator: misfits on a coarse grid (many
/// equal values) or spread finely, by `coarse`.
struct Draws(u64);

impl Draws {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn misfit(&mut self, coarse: bool) -> f64 {
        if coarse {
            0.001 * (self.next() % 7) as f64
        } else {
            (self.next() % 1_000_000) as f64 * 1e-7
        }
    }
}

#[test]
fn a_robots_reference_is_the_others_median_and_deviation_exactly() {
    let mut draws = Draws(0x9e37_79b9_7f4a_7c15);
    for case in 0..400 {
        let coarse = case % 3 == 0;
        let robots = 1 + (draws.next() % 6) as usize;
        let mut shares: Vec<Vec<f64>> = (0..robots)
            .map(|_| {
                let n = (draws.next() % 25) as usize;
                (0..n).map(|_| draws.misfit(coarse)).collect()
            })
            .collect();
        for share in &mut shares {
            sort_share(share);
        }
        let mut reference = Reference::default();
        reference.rebuild(shares.iter().map(|s| s.as_slice()), Time::ZERO);
        for (i, own) in shares.iter().enumerate() {
            let others: Vec<f64> = shares
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .flat_map(|(_, s)| s.iter().copied())
                .collect();
            let got = reference.without(own);
            assert_eq!(got.count, others.len(), "case {case}");
            if others.is_empty() {
                continue;
            }
            let centre = sorted_median(&others);
            let deviations: Vec<f64> = others.iter().map(|m| (m - centre).abs()).collect();
            assert_eq!(got.centre_m, centre, "case {case} robot {i}");
            assert_eq!(
                got.mad_m,
                sorted_median(&deviations),
                "case {case} robot {i}"
            );
        }
    }
}

#[test]
fn it_is_gathered_again_as_fixes_arrive_and_as_time_passes() {
    let mut reference = Reference::default();
    assert!(reference.is_due(Time::ZERO));
    let share: Vec<f64> = (0..16).map(|i| i as f64).collect();
    reference.rebuild(std::iter::once(share.as_slice()), Time::ZERO);
    assert!(!reference.is_due(Time::ZERO));
    // An eighth of 16: the second fix offered since.
    reference.offered();
    assert!(!reference.is_due(Time::ZERO));
    reference.offered();
    assert!(reference.is_due(Time::ZERO));
    reference.rebuild(std::iter::once(share.as_slice()), Time::ZERO);
    let later = Time::ZERO + ickon_proto::time::Duration::from_millis(1_100);
    assert!(reference.is_due(later));
    reference.rebuild(std::iter::once(share.as_slice()), later);
    reference.mark_stale();
    assert!(reference.is_due(later));
}

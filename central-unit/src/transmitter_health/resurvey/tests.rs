use super::*;

/// A seeded noise of about `sigma` (the sum of three uniform draws of a
/// SplitMix64 stream).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    fn draw(&mut self, sigma: f64) -> f64 {
        sigma * (self.uniform() + self.uniform() + self.uniform())
    }
}

/// Receivers 0.3 m above the floor of a robot driving a loop of
/// `radius_m` around `centre` (`n` fixes).
fn loop_of(centre: [f64; 2], radius_m: f64, n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|k| {
            let a = k as f64 / n as f64 * std::f64::consts::TAU;
            [
                centre[0] + radius_m * a.cos(),
                centre[1] + radius_m * a.sin(),
                0.3,
            ]
        })
        .collect()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    Vector3::from(a).metric_distance(&Vector3::from(b))
}

/// The residual a fix at `p` reports of a transmitter the MSUs take at
/// `surveyed` and that is at `truth`, with noise.
fn residual(surveyed: [f64; 3], truth: [f64; 3], p: [f64; 3], noise: &mut Noise) -> f64 {
    dist(truth, p) - dist(surveyed, p) + noise.draw(0.003)
}

const SURVEYED: [f64; 3] = [5.0, 3.0, 3.3];
const MOVED: [f64; 3] = [5.3, 3.0, 3.3];
const NEIGHBOUR: [f64; 3] = [7.5, 3.0, 3.3];

#[test]
fn a_transmitter_knocked_30_cm_is_placed_within_a_centimetre() {
    let mut noise = Noise(1);
    let mut moved = Resurvey::new(SURVEYED, ResurveyConfig::default());
    let mut neighbour = Resurvey::new(NEIGHBOUR, ResurveyConfig::default());
    for (robot, centre) in [("r1", [4.0, 2.0]), ("r2", [6.5, 4.0])] {
        for p in loop_of(centre, 1.5, 60) {
            moved.observe(robot, p, SURVEYED, residual(SURVEYED, MOVED, p, &mut noise));
            neighbour.observe(
                robot,
                p,
                NEIGHBOUR,
                residual(NEIGHBOUR, NEIGHBOUR, p, &mut noise),
            );
        }
    }
    let got = moved.estimate().expect("pinned down");
    assert!(dist(got.position_m, MOVED) < 0.01, "{got:?}");
    assert!(got.sigma_m.iter().all(|s| *s < 0.01), "{got:?}");
    assert_eq!((got.fixes, got.robots), (120, 2));
    // Measured from the same fixes, the neighbour that did not move stays
    // where it is: each transmitter is placed by its own arrivals alone.
    let stays = neighbour.estimate().expect("pinned down");
    assert!(dist(stays.position_m, NEIGHBOUR) < 0.005, "{stays:?}");
}

#[test]
fn too_few_fixes_or_a_straight_path_place_nothing() {
    let mut noise = Noise(2);
    let mut few = Resurvey::new(SURVEYED, ResurveyConfig::default());
    for p in loop_of([4.0, 2.0], 1.5, 39) {
        few.observe("r1", p, SURVEYED, residual(SURVEYED, MOVED, p, &mut noise));
    }
    assert!(few.estimate().is_none(), "39 fixes");
    // Along one line the mirror image across it fits as well.
    let mut line = Resurvey::new(SURVEYED, ResurveyConfig::default());
    for k in 0..100 {
        let p = [1.0 + 0.08 * f64::from(k), 1.0, 0.3];
        line.observe("r1", p, SURVEYED, residual(SURVEYED, MOVED, p, &mut noise));
    }
    assert_eq!(line.len(), 100);
    assert!(line.estimate().is_none());
}

#[test]
fn a_robot_that_places_it_elsewhere_is_outvoted_or_blocks_the_survey() {
    let forged = [5.0, 3.4, 3.3];
    let run = |honest: &[(&str, [f64; 2])]| {
        let mut noise = Noise(3);
        let mut r = Resurvey::new(SURVEYED, ResurveyConfig::default());
        for &(robot, centre) in honest {
            for p in loop_of(centre, 1.5, 60) {
                r.observe(robot, p, SURVEYED, residual(SURVEYED, MOVED, p, &mut noise));
            }
        }
        for p in loop_of([5.0, 3.0], 2.0, 80) {
            r.observe(
                "forger",
                p,
                SURVEYED,
                residual(SURVEYED, forged, p, &mut noise),
            );
        }
        r.estimate()
    };
    let outvoted = run(&[("r1", [4.0, 2.0]), ("r2", [6.5, 4.0])]).expect("two honest robots");
    assert!(dist(outvoted.position_m, MOVED) < 0.01, "{outvoted:?}");
    assert_eq!(outvoted.robots, 2);
    // One against one: nothing is published rather than either's.
    assert_eq!(run(&[("r1", [4.0, 2.0])]), None);
}

#[test]
fn residuals_that_are_not_an_arrivals_are_ignored() {
    let mut r = Resurvey::new(SURVEYED, ResurveyConfig::default());
    r.observe("r1", [1.0, 1.0, 0.3], SURVEYED, f64::NAN);
    r.observe("r1", [1.0, 1.0, 0.3], SURVEYED, 1.5);
    r.observe("r1", [f64::INFINITY, 1.0, 0.3], SURVEYED, 0.1);
    r.observe("r1", [1.0, 1.0, 0.3], [f64::NAN, 0.0, 0.0], 0.1);
    assert!(r.is_empty());
    let mut capped = Resurvey::new(
        SURVEYED,
        ResurveyConfig {
            max_fixes: 5,
            ..ResurveyConfig::default()
        },
    );
    for k in 0..9 {
        capped.observe("r1", [f64::from(k), 1.0, 0.3], SURVEYED, 0.0);
    }
    assert_eq!(capped.len(), 5);
}

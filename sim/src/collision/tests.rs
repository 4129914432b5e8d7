use super::*;
use crate::profile::CollisionModel;
use rand::SeedableRng;

const TIMING: BurstTiming = BurstTiming {
    burst_s: 0.002,
    window_s: 0.0005,
};

fn sound(tx_id: u32, channel: u8, onset_s: f64, path_m: f64) -> Sound {
    Sound {
        tx_id,
        channel,
        onset_s,
        level_db: level_db(&CollisionModel::paper(), path_m),
    }
}

fn heard(tx_id: u32, t_true_s: f64, path_m: f64) -> Heard {
    Heard {
        tx_id,
        receiver_id: 0,
        t_true_s,
        reflected: false,
        path_m,
    }
}

#[test]
fn overlapping_bursts_on_one_channel_collide_and_on_two_channels_do_not() {
    let m = CollisionModel::paper();
    let sounds = [sound(1, 0, 0.010, 3.0), sound(2, 0, 0.0115, 3.0)];
    let l = sounds[1].level_db;
    assert_eq!(
        fate(&m, &TIMING, 0, 0.0115, l, Some(1), &sounds),
        Fate::Collided { with: 0 }
    );
    assert_eq!(
        fate(&m, &TIMING, 0, 0.010, l, Some(0), &sounds),
        Fate::Collided { with: 1 }
    );
    let other_channel = [sound(1, 1, 0.010, 3.0), sound(2, 0, 0.0115, 3.0)];
    assert_eq!(
        fate(&m, &TIMING, 0, 0.0115, l, Some(1), &other_channel),
        Fate::Clear
    );
    // Just outside burst + window: no collision, and the tail of an equal
    // burst, 10 dB under it and falling, is more than 10 dB under the next.
    let apart = [sound(1, 0, 0.010, 3.0), sound(2, 0, 0.0126, 3.0)];
    assert_eq!(
        fate(&m, &TIMING, 0, 0.0126, l, Some(1), &apart),
        Fate::Clear
    );
}

#[test]
fn a_weak_burst_in_a_loud_tail_is_masked_until_the_tail_has_died() {
    let m = CollisionModel::paper();
    // Loud at 1.5 m, weak at 9 m: about 25 dB apart.
    let loud = sound(1, 0, 0.0, 1.5);
    let weak_level = level_db(&m, 9.0);
    let gap = loud.level_db - weak_level;
    assert!(gap > 20.0 && gap < 30.0, "{gap}");
    let sounds = [loud];
    // The tail must fall by gap - 10 (tail) + 10 (snr) dB at 3 dB/ms after the burst.
    let needed_s = TIMING.burst_s + gap / m.reverb_decay_db_per_ms * 1e-3;
    assert_eq!(
        fate(&m, &TIMING, 0, needed_s - 0.001, weak_level, None, &sounds),
        Fate::Masked { by: 0 }
    );
    assert_eq!(
        fate(&m, &TIMING, 0, needed_s + 0.001, weak_level, None, &sounds),
        Fate::Clear
    );
    // A burst before the loud one is not masked by it.
    assert_eq!(
        fate(&m, &TIMING, 0, -0.005, weak_level, None, &sounds),
        Fate::Clear
    );
}

#[test]
fn collisions_are_lost_or_misdecoded_as_the_stronger_at_the_earlier_onset() {
    let sounds = [sound(1, 0, 0.0100, 2.0), sound(2, 0, 0.0110, 6.0)];
    let detections = [
        Detection {
            heard: heard(1, 0.0100, 2.0),
            channel: 0,
            own: Some(0),
        },
        Detection {
            heard: heard(2, 0.0110, 6.0),
            channel: 0,
            own: Some(1),
        },
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut lost = CollisionModel::paper();
    lost.misdecode_probability = 0.0;
    let mut counts = CollisionCounts::default();
    let out = resolve(&lost, &TIMING, &detections, &sounds, &mut rng, &mut counts);
    assert!(out.is_empty());
    assert_eq!(
        counts,
        CollisionCounts {
            detected: 2,
            collided: 2,
            misdecoded: 0,
            masked: 0,
            blocked_detected: 0,
            blocked_lost: 0,
        }
    );
    assert_eq!(counts.lost(), 2);
    assert!((counts.lost_share() - 1.0).abs() < 1e-12);

    let mut always = CollisionModel::paper();
    always.misdecode_probability = 1.0;
    let mut counts = CollisionCounts::default();
    let out = resolve(
        &always,
        &TIMING,
        &detections,
        &sounds,
        &mut rng,
        &mut counts,
    );
    // Both decode as the stronger (tx 1) at the earlier onset; one per id is kept.
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].tx_id, 1);
    assert!((out[0].t_true_s - 0.0100).abs() < 1e-12);
    assert_eq!(counts.misdecoded, 2);
    assert_eq!(counts.lost(), 0);
}

#[test]
fn level_falls_with_distance_and_absorption_and_never_blows_up_at_zero() {
    let m = CollisionModel::paper();
    assert!((level_db(&m, 1.0) + 1.3).abs() < 1e-12);
    assert!(level_db(&m, 2.0) < level_db(&m, 1.0) - 6.0);
    assert!(level_db(&m, 0.0).is_finite());
    assert_eq!(level_db(&m, 0.0), level_db(&m, 0.1));
}

#[test]
fn no_sounds_no_counts() {
    let c = CollisionCounts::default();
    assert_eq!(c.lost_share(), 0.0);
}

//! The real-time world fed random sequences of events (fuzz target, see
//! `ickon_proto::fuzz`): schedules and burst reports with extreme fields
//! (forged epochs, cycles, times), and a clock that goes backwards. It
//! never panics, keeps its cycle tables bounded, and its sensors give
//! finite samples.

use std::sync::LazyLock;

use crate::realtime::{RealtimeWorld, WorldEvent, WorldOutput};
use ickon_proto::fuzz::extreme::offset_ns;
use ickon_proto::fuzz::values::draw;
use ickon_proto::fuzz::{config_for, entropy};
use ickon_proto::msg::control::{Burst, Schedule};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};
use ickon_sim::NoiseProfile;
use proptest::prelude::*;

const EPOCH: u64 = 1_000;

#[derive(Debug, Clone)]
struct Act {
    kind: u8,
    step_ns: i64,
    e: Vec<u8>,
}

fn act() -> impl Strategy<Value = Act> {
    // The world's clock is its own: forward by up to 300 ms or backwards
    // (a clock step); the extremes are in the messages.
    (any::<u8>(), -200_000_000i64..300_000_000, entropy()).prop_map(|(kind, step_ns, e)| Act {
        kind,
        step_ns,
        e,
    })
}

/// The site and its schedule, the same for every case: parsed and
/// computed once (half of a case's time when built per case).
static SITE: LazyLock<(Site, Schedule)> = LazyLock::new(|| {
    let site = Site::default_site();
    let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
    let schedule = Schedule {
        epoch: EPOCH,
        ..ickon_central::compute_schedule(&site, &cells, 1, 0).expect("schedule")
    };
    (site, schedule)
});

fn run(profile: usize, acts: &[Act], offsets: &[i64]) -> Result<(), TestCaseError> {
    let (site, schedule) = &*SITE;
    let profile = NoiseProfile::by_name(NoiseProfile::names()[profile]).expect("profile");
    let ids = vec!["r1".to_string(), "r2".to_string()];
    let mut world = RealtimeWorld::new(site, &ids, &profile, 7).expect("robots of the site");
    let mut now = Time::from_nanos(1_000_000_000);
    let mut cycle = 0u64;
    for (i, a) in acts.iter().enumerate() {
        now = now + Duration::from_nanos(a.step_ns);
        let plausible = a.e.first().is_some_and(|b| *b < 160);
        let off = offsets[i % offsets.len()];
        let ev = match a.kind % 4 {
            0 => WorldEvent::Schedule(if plausible {
                schedule.clone()
            } else {
                match draw::<Schedule>(&a.e) {
                    Some(s) => s,
                    None => continue,
                }
            }),
            1 | 2 => {
                let Some(mut b) = draw::<Burst>(&a.e) else {
                    continue;
                };
                if plausible {
                    let e = &schedule.emissions[usize::from(a.kind) % schedule.emissions.len()];
                    cycle += u64::from(a.kind & 0x40 != 0);
                    b.epoch = EPOCH;
                    b.cycle = cycle;
                    b.tx_id = e.tx_id;
                    b.actual = now + e.offset + Duration::from_nanos(off / 1_000);
                }
                WorldEvent::Burst(b)
            }
            _ => WorldEvent::Tick,
        };
        for o in world.handle(now, ev) {
            match o {
                WorldOutput::Imu(_, m) => prop_assert!(m.gyro_z_rad_s.is_finite()),
                WorldOutput::Odometry(_, m) => prop_assert!(m.x_m.is_finite() && m.y_m.is_finite()),
                WorldOutput::Truth(_, m) => prop_assert!(m.x_m.is_finite() && m.y_m.is_finite()),
                WorldOutput::Arrivals(_, m) => {
                    prop_assert!(
                        m.arrivals.len() <= 64 * schedule.emissions.len(),
                        "{}",
                        m.arrivals.len()
                    );
                }
                WorldOutput::Ranges(..) => {}
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config_for(24))]

    #[test]
    fn fuzz_world(
        profile in 0usize..3,
        acts in proptest::collection::vec(act(), 1..40),
        offsets in proptest::collection::vec(offset_ns(20_000_000_000), 1..4),
    ) {
        run(profile, &acts, &offsets)?;
    }
}

//! The host's side of the device protocol (`ickon_device::BoardHost`)
//! against emulated boards with their own clocks and faults, in virtual
//! time: handshake, clock fit, bursts fired where they were armed, arrivals
//! back on the host's clock, a wrong board refused, garbage and drops
//! survived, a silent board found again.

use crate::board::{BoardFaults, BoardSpec, EmulatedBoard};
use ickon_device::{BoardHost, BoardKind, HostEvent, HostState};

/// One millisecond, nanoseconds.
const MS: i64 = 1_000_000;
/// One way of the emulated line (a 115200-baud frame is about 2 ms).
const LINE_NS: i64 = 2 * MS;

/// Runs host and board for `ms` milliseconds of virtual time from `t`,
/// each step 1 ms, bytes taking [`LINE_NS`] each way; returns the host's
/// events and the board's emissions, and the new time.
struct Bench {
    host: BoardHost,
    board: EmulatedBoard,
    t: i64,
    to_board: Vec<(i64, Vec<u8>)>,
    to_host: Vec<(i64, Vec<u8>)>,
    events: Vec<HostEvent>,
    emissions: Vec<crate::board::Emission>,
}

impl Bench {
    fn new(expected: BoardKind, spec: BoardSpec) -> Self {
        let t = 10_000 * MS;
        let mut host = BoardHost::new(expected);
        let hello = host.connected(t);
        Self {
            host,
            board: EmulatedBoard::new(spec, t - 5_000 * MS),
            t,
            to_board: vec![(t + LINE_NS, hello)],
            to_host: Vec::new(),
            events: Vec::new(),
            emissions: Vec::new(),
        }
    }

    fn run(&mut self, ms: i64) {
        for _ in 0..ms {
            self.t += MS;
            let t = self.t;
            let (due, later): (Vec<_>, Vec<_>) =
                self.to_board.drain(..).partition(|(at, _)| *at <= t);
            self.to_board = later;
            for (_, bytes) in due {
                let reply = self.board.on_bytes(t, &bytes);
                self.to_host.push((t + LINE_NS, reply));
            }
            let (fired, emissions) = self.board.fire_due(t);
            self.emissions.extend(emissions);
            self.to_host.push((t + LINE_NS, fired));
            let (due, later): (Vec<_>, Vec<_>) =
                self.to_host.drain(..).partition(|(at, _)| *at <= t);
            self.to_host = later;
            for (_, bytes) in due {
                let ev = self.host.on_bytes(t, &bytes);
                self.events.extend(ev);
            }
            let (out, _, ev) = self.host.poll(t);
            self.events.extend(ev);
            if !out.is_empty() {
                self.to_board.push((t + LINE_NS, out));
            }
        }
    }

    fn arm(&mut self, tx: u32, at: i64, tag: u64) {
        let bytes = self.host.arm(tx, at, tag).expect("armed");
        self.to_board.push((self.t + LINE_NS, bytes));
    }
}

fn drifting_transmitter(seed: u64) -> BoardSpec {
    let mut spec = BoardSpec::transmitter(&[11, 12, 13, 14], seed);
    spec.clock_offset_ns = 123_456_789;
    spec.drift_ppm = 60.0;
    spec.jitter_ns = 2_000.0;
    spec
}

#[test]
fn bursts_fire_where_armed_on_a_drifting_board() {
    let mut b = Bench::new(BoardKind::Transmitter, drifting_transmitter(1));
    // Long enough for a drift: exchanges spanning more than 2 s.
    b.run(6_000);
    assert_eq!(b.host.state(), HostState::Ready);
    assert!(
        matches!(b.events[0], HostEvent::Identified(_)),
        "{:?}",
        b.events
    );
    for i in 0..20u64 {
        let at = b.t + 20 * MS;
        b.arm(11 + (i % 4) as u32, at, i);
        b.run(40);
    }
    let fired: Vec<_> = b
        .events
        .iter()
        .filter_map(|e| match e {
            HostEvent::Fired {
                tag,
                fired_host_ns,
                armed_host_ns,
                ..
            } => Some((*tag, *fired_host_ns, *armed_host_ns)),
            _ => None,
        })
        .collect();
    assert_eq!(fired.len(), 20, "{:?}", b.events);
    assert_eq!(b.emissions.len(), 20);
    for ((tag, reported, armed), emission) in fired.iter().zip(&b.emissions) {
        // Host time is the reference here: the burst left within the
        // symmetric line's clock error and the board's jitter of its time.
        let err = emission.reference_ns - armed;
        assert!(
            err.abs() < 20_000,
            "burst {tag} left {err} ns from its time"
        );
        // The report is the board's stamp, mapped back: the true emission.
        let report_err = reported - emission.reference_ns;
        assert!(
            report_err.abs() < 20_000,
            "burst {tag} reported {report_err} ns off"
        );
    }
}

#[test]
fn a_receiver_board_on_a_cells_port_is_refused_by_name() {
    let mut b = Bench::new(BoardKind::Transmitter, BoardSpec::receiver(6, 2));
    b.run(500);
    assert_eq!(b.host.state(), HostState::WrongBoard);
    let why = b.events.iter().find_map(|e| match e {
        HostEvent::WrongBoard(w) => Some(w.clone()),
        _ => None,
    });
    assert_eq!(
        why.as_deref(),
        Some("a receiver board answered where a transmitter board was expected")
    );
    assert!(b.host.arm(11, b.t + 20 * MS, 0).is_err());
}

#[test]
fn arrivals_come_back_on_the_host_clock_as_one_group() {
    let mut spec = BoardSpec::receiver(6, 3);
    spec.drift_ppm = -40.0;
    let mut b = Bench::new(BoardKind::Receiver, spec);
    b.run(6_000);
    assert_eq!(b.host.state(), HostState::Ready);
    let heard: Vec<(u32, u8, i64)> = (0..40)
        .map(|i| (i, (i % 6) as u8, b.t - 30 * MS + i64::from(i) * 100_000))
        .collect();
    let t = b.t;
    let bytes = b.board.arrivals(t, &heard);
    b.to_host.push((t + LINE_NS, bytes));
    b.run(10);
    let groups: Vec<_> = b
        .events
        .iter()
        .filter_map(|e| match e {
            HostEvent::Arrivals { arrivals: a, .. } => Some(a.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(groups.len(), 1, "40 arrivals span 3 frames of one group");
    assert_eq!(groups[0].len(), 40);
    for (a, (tx, rx, at)) in groups[0].iter().zip(&heard) {
        assert_eq!((a.tx_id, a.receiver), (*tx, *rx));
        assert!((a.host_ns - at).abs() < 20_000, "{} vs {at}", a.host_ns);
    }
}

#[test]
fn a_board_with_motion_reports_wheel_ticks_and_gyro_on_the_host_clock() {
    let mut spec = BoardSpec::receiver(6, 6).with_motion();
    spec.drift_ppm = 35.0;
    let mut b = Bench::new(BoardKind::Receiver, spec);
    b.run(6_000);
    assert_eq!(b.host.state(), HostState::Ready);
    let sampled_at = b.t - 3 * MS;
    let mut bytes = b.board.wheel_ticks(sampled_at, 1_234, -56);
    bytes.extend(b.board.imu(sampled_at, -0.25));
    // A saturated gyro reads the message's limit, not a wrapped value.
    bytes.extend(b.board.imu(sampled_at, 1e6));
    b.to_host.push((b.t + LINE_NS, bytes));
    b.run(10);
    let ticks: Vec<_> = b
        .events
        .iter()
        .filter_map(|e| match e {
            HostEvent::WheelTicks {
                host_ns,
                left,
                right,
            } => Some((*host_ns, *left, *right)),
            _ => None,
        })
        .collect();
    assert_eq!(ticks.len(), 1);
    assert_eq!((ticks[0].1, ticks[0].2), (1_234, -56));
    assert!((ticks[0].0 - sampled_at).abs() < 20_000, "{ticks:?}");
    let rates: Vec<f64> = b
        .events
        .iter()
        .filter_map(|e| match e {
            HostEvent::Imu { gyro_z_rad_s, .. } => Some(*gyro_z_rad_s),
            _ => None,
        })
        .collect();
    assert_eq!(rates.len(), 2);
    assert!((rates[0] + 0.25).abs() < 1e-6, "{rates:?}");
    assert!(
        (rates[1] - f64::from(i32::MAX) * 1e-6).abs() < 1e-3,
        "{rates:?}"
    );
}

#[test]
fn groups_keep_the_boards_number() {
    let mut b = Bench::new(BoardKind::Receiver, BoardSpec::receiver(6, 8));
    b.run(6_000);
    for _ in 0..3 {
        let t = b.t;
        let bytes = b.board.arrivals(t, &[(11, 0, t - 5 * MS)]);
        b.to_host.push((t + LINE_NS, bytes));
        b.run(5);
    }
    let groups: Vec<u16> = b
        .events
        .iter()
        .filter_map(|e| match e {
            HostEvent::Arrivals { group, .. } => Some(*group),
            _ => None,
        })
        .collect();
    assert_eq!(groups, [1, 2, 3]);
}

#[test]
fn garbage_and_dropped_frames_cost_frames_not_the_link() {
    let mut spec = drifting_transmitter(4);
    spec.faults = BoardFaults {
        garbage: 0.3,
        drop: 0.1,
        mute_after_ns: None,
    };
    let mut b = Bench::new(BoardKind::Transmitter, spec);
    b.run(5_000);
    assert_eq!(b.host.state(), HostState::Ready, "{:?}", b.host.report(b.t));
    for i in 0..50u64 {
        let at = b.t + 20 * MS;
        b.arm(12, at, i);
        b.run(30);
    }
    let report = b.host.report(b.t);
    let fired = report.counters.fired;
    // About 60 % of the reports survive 30 % garbage and 10 % drops.
    assert!(fired >= 20, "{report:?}");
    assert!(
        report.counters.refused > 0,
        "the garbage was seen: {report:?}"
    );
    assert!(
        report.counters.lost > 0,
        "the drops were counted: {report:?}"
    );
}

#[test]
fn a_board_that_stops_answering_is_found_silent_and_greeted_again() {
    let mut spec = drifting_transmitter(5);
    spec.faults.mute_after_ns = Some(8_000 * MS);
    let mut b = Bench::new(BoardKind::Transmitter, spec);
    b.run(2_000);
    assert_eq!(b.host.state(), HostState::Ready);
    b.run(5_000);
    assert!(
        b.events.contains(&HostEvent::Silent),
        "{:?}",
        b.host.report(b.t)
    );
    assert_eq!(b.host.state(), HostState::AwaitingIdentity);
    assert!(b.host.report(b.t).counters.handshakes >= 2);
}

/// A transmitter board of the lab's cell c1 with the typical air sensor
/// (`fault` from 0 s on), reading the `building` air from the bench's
/// board start.
fn board_with_air(fault: Option<ickon_sim::air_sensor::SensorFaultKind>) -> BoardSpec {
    use ickon_sim::air_sensor::{AirSensor, AirSensors, SensorFault, board_position};
    let site = ickon_proto::site::Site::default_site();
    let mut sensors = AirSensors::typical();
    sensors.faults = fault
        .into_iter()
        .map(|kind| SensorFault {
            cell: "c1".into(),
            at_s: 0.0,
            kind,
        })
        .collect();
    let at = board_position(&site, "c1").unwrap();
    BoardSpec::transmitter(&[11, 12, 13, 14], 3).with_air_sensor(crate::board::BoardAir {
        sensor: AirSensor::new("c1", at, &sensors, 3),
        field: ickon_sim::air::AirField::new(&site, &ickon_sim::air::Air::building(), 1.0),
        start_ns: 5_000 * MS,
    })
}

fn air_readings(events: &[HostEvent]) -> Vec<(i64, f64)> {
    events
        .iter()
        .filter_map(|e| match e {
            HostEvent::AirTemperature {
                host_ns,
                temperature_c,
            } => Some((*host_ns, *temperature_c)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_board_with_an_air_sensor_is_asked_once_a_second_and_its_readings_come_back() {
    let mut b = Bench::new(BoardKind::Transmitter, board_with_air(None));
    b.run(10_500);
    let r = air_readings(&b.events);
    assert!((10..=11).contains(&r.len()), "{} readings", r.len());
    // The air under the ceiling of a hall at its coldest: a few degrees
    // under the site's 20, with the sensor's bias, on the host's clock
    // within the line's delay of when it was asked.
    assert!(r.iter().all(|&(_, c)| (5.0..25.0).contains(&c)), "{r:?}");
    assert!(
        r.windows(2)
            .all(|w| (w[1].0 - w[0].0 - 1_000 * MS).abs() < 10 * MS)
    );
    assert_eq!(b.host.report(b.t).counters.refused, 0);
    assert!(b.host.report(b.t).air_temperature_c.is_some());
    assert!(
        b.host.report(b.t).summary().contains(" C"),
        "shown to the operator"
    );
}

#[test]
fn a_board_without_a_sensor_is_never_asked_and_a_failed_one_reads_not_a_number() {
    let mut b = Bench::new(BoardKind::Transmitter, drifting_transmitter(5));
    b.run(5_000);
    assert!(air_readings(&b.events).is_empty());
    assert_eq!(
        b.host.report(b.t).counters.refused,
        0,
        "nothing refused either way"
    );
    let mut b = Bench::new(
        BoardKind::Transmitter,
        board_with_air(Some(ickon_sim::air_sensor::SensorFaultKind::NotANumber)),
    );
    b.run(3_000);
    let r = air_readings(&b.events);
    assert!(!r.is_empty() && r.iter().all(|(_, c)| c.is_nan()));
}

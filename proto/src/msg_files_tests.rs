//! Every `ickon_msgs` `.msg` file describes exactly the bytes `proto` writes:
//! each message type is encoded with `crate::encode`, then decoded by
//! a small CDR reader that knows nothing but the `.msg` file, and the result
//! must use every byte and equal the value field by field. This is what a
//! ROS 2 tool (Foxglove, `ros2 bag`) does with a recording's schema.

use std::collections::BTreeSet;

use crate::msg::control::{
    AirTemperature, Burst, CellStatus, CycleTrigger, Emission, Firing, RouterLink, Schedule,
    SiteInfo, SurveyCalibration, TransmitterOffset,
};
use crate::msg::robot::{
    Arrival, Fix, FixQuality, Imu, MsuStatus, ObstacleRanges, Odometry, PoseStatus, RobotSummary,
    Truth, UltrasoundArrivals,
};
use crate::msg::ros_msgs::{MSG_FILES, PACKAGE, msg_file, own_schema};
use crate::{Duration, Time, encode};
use serde_json::{Map, Value, json};

/// One field of a `.msg` file.
#[derive(Debug)]
struct Field {
    ty: String,
    array: Option<Option<usize>>,
    name: String,
}

/// Fields and constants of a `.msg` text.
fn parse(text: &str) -> (Vec<Field>, Vec<(String, String)>) {
    let mut fields = Vec::new();
    let mut constants = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap().trim();
        if line.is_empty() {
            continue;
        }
        let mut parts = line.split_whitespace();
        let ty = parts.next().unwrap();
        let rest: String = parts.collect::<Vec<_>>().join(" ");
        if let Some((name, value)) = rest.split_once('=') {
            constants.push((name.trim().to_string(), value.trim().to_string()));
            continue;
        }
        let name = rest.split_whitespace().next().unwrap().to_string();
        let (base, array) = match ty.split_once('[') {
            Some((b, n)) => {
                let n = n.trim_end_matches(']');
                (b, Some((!n.is_empty()).then(|| n.parse().unwrap())))
            }
            None => (ty, None),
        };
        fields.push(Field {
            ty: base.to_string(),
            array,
            name,
        });
    }
    (fields, constants)
}

/// A CDR little-endian reader; alignment counts from after the 4-byte header.
struct Reader<'a> {
    body: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize, align: usize) -> &[u8] {
        self.pos = self.pos.div_ceil(align) * align;
        let out = &self.body[self.pos..self.pos + n];
        self.pos += n;
        out
    }

    fn primitive(&mut self, ty: &str) -> Value {
        macro_rules! le {
            ($t:ty) => {{
                let n = std::mem::size_of::<$t>();
                <$t>::from_le_bytes(self.take(n, n).try_into().unwrap())
            }};
        }
        match ty {
            "bool" => {
                let b = self.take(1, 1)[0];
                assert!(b <= 1, "bool byte {b}");
                json!(b == 1)
            }
            "uint8" => json!(le!(u8)),
            "uint32" => json!(le!(u32)),
            "int32" => json!(le!(i32)),
            "uint64" => json!(le!(u64)),
            "int64" => json!(le!(i64)),
            "float64" => json!(le!(f64)),
            "string" => {
                let len = le!(u32) as usize;
                let bytes = self.take(len, 1);
                assert_eq!(bytes.last(), Some(&0), "string without its NUL");
                json!(std::str::from_utf8(&bytes[..len - 1]).unwrap())
            }
            other => {
                let name = other
                    .strip_prefix(&format!("{PACKAGE}/"))
                    .unwrap_or_else(|| panic!("unknown type {other}"));
                self.message(msg_file(name).unwrap_or_else(|| panic!("no {name}.msg")))
            }
        }
    }

    fn message(&mut self, text: &str) -> Value {
        let (fields, _) = parse(text);
        let mut out = Map::new();
        for f in fields {
            let value = match f.array {
                None => self.primitive(&f.ty),
                Some(fixed) => {
                    let n = match fixed {
                        Some(n) => n,
                        None => u32::from_le_bytes(self.take(4, 4).try_into().unwrap()) as usize,
                    };
                    Value::Array((0..n).map(|_| self.primitive(&f.ty)).collect())
                }
            };
            out.insert(f.name, value);
        }
        Value::Object(out)
    }
}

/// The value as the `.msg` file sees it: enum variants become their constant.
fn as_msg_sees_it(value: Value, text: &str) -> Value {
    let (fields, constants) = parse(text);
    let Value::Object(mut map) = value else {
        return value;
    };
    let mut out = Map::new();
    for f in fields {
        let Some(v) = map.remove(&f.name) else {
            panic!("field {} of the .msg is not in the Rust type", f.name)
        };
        let v = match (&v, f.ty.strip_prefix(&format!("{PACKAGE}/"))) {
            (Value::String(variant), None) if f.ty != "string" => {
                let constant = format!("{}_{}", f.name.to_uppercase(), variant.to_uppercase());
                let (_, n) = constants
                    .iter()
                    .find(|(c, _)| *c == constant)
                    .unwrap_or_else(|| panic!("no constant {constant}"));
                json!(n.parse::<u64>().unwrap())
            }
            (Value::Array(items), Some(inner)) => Value::Array(
                items
                    .iter()
                    .map(|i| as_msg_sees_it(i.clone(), msg_file(inner).unwrap()))
                    .collect(),
            ),
            (Value::Object(_), Some(inner)) => as_msg_sees_it(v.clone(), msg_file(inner).unwrap()),
            _ => v,
        };
        out.insert(f.name, v);
    }
    assert!(map.is_empty(), "Rust fields missing from the .msg: {map:?}");
    Value::Object(map_sorted(out))
}

fn map_sorted(m: Map<String, Value>) -> Map<String, Value> {
    m.into_iter().collect()
}

fn check<T: serde::Serialize>(name: &str, value: &T, checked: &mut BTreeSet<String>) {
    let bytes = encode(value).unwrap();
    assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
    let text = msg_file(name).unwrap_or_else(|| panic!("no {name}.msg"));
    let mut reader = Reader {
        body: &bytes[4..],
        pos: 0,
    };
    let decoded = reader.message(text);
    assert_eq!(
        reader.pos,
        bytes.len() - 4,
        "{name}: the .msg layout leaves bytes unread"
    );
    let expected = as_msg_sees_it(serde_json::to_value(value).unwrap(), text);
    let Value::Object(decoded) = decoded else {
        unreachable!()
    };
    assert_eq!(Value::Object(map_sorted(decoded)), expected, "{name}");
    assert!(own_schema(name).is_some());
    checked.insert(name.to_string());
}

fn arrival(k: u32) -> Arrival {
    Arrival {
        tx_id: 10 + k,
        receiver_id: (k % 6) as u8,
        t_arrival: Time::from_nanos(1_700_000_000_123_456_789 + i64::from(k) * 977),
    }
}

#[test]
fn every_message_type_decodes_by_its_msg_file_alone() {
    let mut checked = BTreeSet::new();
    let t = Time::from_nanos(1_764_000_000_987_654_321);
    check("Arrival", &arrival(3), &mut checked);
    // Odd counts and odd string lengths exercise the padding rules.
    check(
        "UltrasoundArrivals",
        &UltrasoundArrivals {
            seq: 42,
            arrivals: (0..3).map(arrival).collect(),
        },
        &mut checked,
    );
    check(
        "Odometry",
        &Odometry {
            stamp: t,
            x_m: 1.25,
            y_m: -3.5,
            theta_rad: 7.1,
            left_ticks: -123_456,
            right_ticks: 987_654_321_012,
        },
        &mut checked,
    );
    check(
        "Imu",
        &Imu {
            stamp: t,
            gyro_z_rad_s: -0.0123,
        },
        &mut checked,
    );
    check(
        "ObstacleRanges",
        &ObstacleRanges {
            stamp: t,
            left_m: 1.5,
            left_valid: true,
            right_m: 0.0,
            right_valid: false,
            left_ir_m: 0.12,
            left_ir_valid: true,
            right_ir_m: 0.2,
            right_ir_valid: true,
        },
        &mut checked,
    );
    let fix = |quality, heading_valid| Fix {
        stamp: t,
        arrivals_seq: 42,
        x_m: 2.5,
        y_m: 1.75,
        z_m: 0.5,
        covariance: [1e-4, 2e-6, 0.0, 2e-6, 3e-4, 0.0, 0.0, 0.0, 1e-6],
        heading_rad: 0.3,
        heading_valid,
        used: vec![11, 12, 13],
        rejected: vec![14],
        residuals_m: vec![0.001, -0.002, 0.0005],
        quality,
        survey_version: 1_764_000_000,
        unused: vec![9],
        unused_residuals_m: vec![0.31],
    };
    for status in [PoseStatus::NoOdometry, PoseStatus::Localising] {
        check(
            "RobotSummary",
            &RobotSummary {
                seq: 7,
                stamp: t,
                x_m: 1.5,
                y_m: -2.25,
                theta_rad: 0.7,
                covariance: [1e-4, 0.0, 0.0, 0.0, 2e-4, 0.0, 0.0, 0.0, 1e-3],
                estimator: "tdoa-ekf".into(),
                fix_seq: 41,
                status,
                vx_m_s: 0.5,
                vy_m_s: -0.125,
                velocity_span_s: 0.48,
                fixes_solved: 3,
                fixes: vec![fix(FixQuality::Good, true), fix(FixQuality::Minimal, false)],
            },
            &mut checked,
        );
    }
    for (quality, heading_valid) in [(FixQuality::Suspect, true), (FixQuality::Ambiguous, false)] {
        check(
            "Fix",
            &Fix {
                stamp: t,
                arrivals_seq: 42,
                x_m: 2.5,
                y_m: 1.75,
                z_m: 0.5,
                covariance: [1e-4, 2e-6, 0.0, 2e-6, 3e-4, 0.0, 0.0, 0.0, 1e-6],
                heading_rad: 0.3,
                heading_valid,
                used: vec![11, 12, 13],
                rejected: vec![14],
                residuals_m: vec![0.001, -0.002, 0.0005],
                quality,
                survey_version: 1_764_000_000,
                unused: vec![9],
                unused_residuals_m: vec![0.31],
            },
            &mut checked,
        );
    }
    check(
        "Truth",
        &Truth {
            stamp: t,
            robot_clock: Time::from_nanos(t.as_nanos() + 5_000_123),
            x_m: 3.0,
            y_m: 4.0,
            theta_rad: -2.0,
            v_m_s: 0.3,
            omega_rad_s: 0.1,
        },
        &mut checked,
    );
    check(
        "SiteInfo",
        &SiteInfo {
            site: "lab".into(),
            version: 3,
            site_toml: "name = \"lab\"\n# odd\n".into(),
        },
        &mut checked,
    );
    let emission = |tx_id: u32, cell: &str| Emission {
        tx_id,
        cell_id: cell.into(),
        offset: Duration::from_millis(i64::from(tx_id)),
        slot: tx_id % 4,
    };
    check("Emission", &emission(5, "c12"), &mut checked);
    check(
        "Firing",
        &Firing {
            tx_id: 31,
            offset: Duration::from_millis(12),
        },
        &mut checked,
    );
    check(
        "Schedule",
        &Schedule {
            version: 2,
            effective_cycle: 1000,
            cycle_period: Duration::from_millis(380),
            slot_length: Duration::from_millis(40),
            emissions: vec![emission(1, "c1"), emission(2, "cell-22")],
            active_cells: vec!["c1".into(), "cell-22".into(), "x".into()],
            epoch: 1_764_000_000_000_000_000,
        },
        &mut checked,
    );
    check(
        "CycleTrigger",
        &CycleTrigger {
            cycle: 77,
            start: t,
            schedule_version: 2,
            epoch: 99,
            firing: vec![
                Firing {
                    tx_id: 11,
                    offset: Duration::from_millis(3),
                },
                Firing {
                    tx_id: 42,
                    offset: Duration::ZERO,
                },
            ],
            cycle_period: Duration::from_millis(95),
        },
        &mut checked,
    );
    check(
        "Burst",
        &Burst {
            cell_id: "c3".into(),
            tx_id: 31,
            cycle: 77,
            scheduled: t,
            actual: Time::from_nanos(t.as_nanos() + 12_345),
            epoch: 99,
        },
        &mut checked,
    );
    check(
        "CellStatus",
        &CellStatus {
            cell_id: "c2x".into(),
            stamp: t,
            offset_ns: -50_000_000,
            drift_ppb: 20_000,
            offset_sigma_ns: 5_000,
            sync_samples: 8,
            last_cycle_fired: 76,
            cycles_fired: 70,
            slots_skipped: 1,
            faults: vec!["central unit silent".into()],
            inputs_refused: 4,
            device: String::new(),
        },
        &mut checked,
    );
    check(
        "AirTemperature",
        &AirTemperature {
            cell_id: "c2x".into(),
            stamp: t,
            temperature_c: 21.37,
        },
        &mut checked,
    );
    check(
        "RouterLink",
        &RouterLink {
            node_id: "r7".into(),
            back_unix_ms: 1_796_000_000_123,
            losses: 2,
        },
        &mut checked,
    );
    check(
        "MsuStatus",
        &MsuStatus {
            stamp: t,
            receivers: "receiver board on tcp:10.0.0.9:4001: link up, ready".into(),
        },
        &mut checked,
    );
    let offset = TransmitterOffset {
        tx_id: 31,
        offset_m: [0.004, -0.002, 0.011],
        sigma_m: [0.006, 0.007, 0.003],
        late_m: -0.0071,
        late_sigma_m: 0.0042,
        left_out: true,
    };
    check("TransmitterOffset", &offset, &mut checked);
    check(
        "SurveyCalibration",
        &SurveyCalibration {
            epoch: 99,
            version: 1_764_000_001,
            fixes_taken: 2_021,
            offsets: vec![
                offset,
                TransmitterOffset {
                    tx_id: 32,
                    ..offset
                },
            ],
            speed_of_sound_m_s: 346.25,
            speed_of_sound_sigma_m_s: 0.125,
        },
        &mut checked,
    );
    let files: BTreeSet<String> = MSG_FILES.iter().map(|(n, _)| n.to_string()).collect();
    assert_eq!(checked, files, "every .msg file is checked, and only those");
}

#[test]
fn the_msg_files_on_disk_are_the_ones_compiled_in() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("msg");
    let mut on_disk = BTreeSet::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "msg") {
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            assert_eq!(
                msg_file(&name),
                Some(std::fs::read_to_string(&path).unwrap().as_str()),
                "{name}.msg"
            );
            on_disk.insert(name);
        }
    }
    let compiled: BTreeSet<String> = MSG_FILES.iter().map(|(n, _)| n.to_string()).collect();
    assert_eq!(on_disk, compiled);
}

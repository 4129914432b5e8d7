use super::*;
use crate::air::Air;

fn field() -> (Site, AirField) {
    let site = Site::default_site();
    let air = AirField::new(&site, &Air::building(), 1.0);
    (site, air)
}

#[test]
fn the_same_seed_reads_the_same_and_another_seed_another_bias() {
    let (site, air) = field();
    let spec = AirSensors::typical();
    let read = |seed| {
        let mut s = CellAirSensors::new(&site, &spec, seed).unwrap();
        s.due(&air, 30.0)
    };
    assert_eq!(read(7), read(7));
    assert_ne!(read(7), read(8));
    // A reading a second of every cell, from 0 to 30 s.
    assert_eq!(read(7).len(), 31 * site.cells.len());
    assert!(CellAirSensors::new(&site, &AirSensors::default(), 7).is_none());
}

#[test]
fn a_sensor_reads_the_air_at_its_board_with_its_bias_and_noise() {
    let (site, air) = field();
    let at = board_position(&site, "c1").unwrap();
    let spec = AirSensors::typical();
    let mut s = AirSensor::new("c1", at, &spec, 3);
    // Still air at one moment: the readings scatter by the noise about
    // the air plus the bias.
    let truth = air.temperature_c(at, 100.0);
    let n = 2_000;
    let r: Vec<f64> = (0..n).map(|_| s.read(&air, 100.0)).collect();
    let mean = r.iter().sum::<f64>() / n as f64;
    let sd = (r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    assert!(
        (mean - truth - s.bias_c()).abs() < 0.01,
        "mean {mean}, air {truth}"
    );
    assert!((sd - 0.1).abs() < 0.01, "noise {sd}");
    assert!(
        r.iter()
            .all(|v| ((v * 100.0).round() - v * 100.0).abs() < 1e-6)
    );
    // The board hangs under the ceiling: warmer than the air at 1.5 m.
    assert!(truth > air.temperature_c([at[0], at[1], 1.5], 100.0) + 1.0);
    // Biases over many boards: about the profile's sigma.
    let biases: Vec<f64> = (0..400)
        .map(|seed| AirSensor::new("c1", at, &spec, seed).bias_c())
        .collect();
    let rms = (biases.iter().map(|b| b * b).sum::<f64>() / 400.0).sqrt();
    assert!((rms - 0.5).abs() < 0.07, "bias rms {rms}");
}

#[test]
fn faults_make_a_sensor_stuck_not_a_number_or_jumping_from_their_time() {
    let (site, air) = field();
    let at = board_position(&site, "c1").unwrap();
    let fault = |kind| AirSensors {
        faults: vec![SensorFault {
            cell: "c1".into(),
            at_s: 10.0,
            kind,
        }],
        ..AirSensors::typical()
    };
    let mut stuck = AirSensor::new("c1", at, &fault(SensorFaultKind::Stuck), 1);
    let before = stuck.read(&air, 9.0);
    assert!((10..20).all(|t| stuck.read(&air, f64::from(t)) == before));
    let mut nan = AirSensor::new("c1", at, &fault(SensorFaultKind::NotANumber), 1);
    assert!(nan.read(&air, 9.0).is_finite());
    assert!(nan.read(&air, 10.0).is_nan());
    let mut jumping = AirSensor::new("c1", at, &fault(SensorFaultKind::Jumping), 1);
    let r: Vec<f64> = (10..14).map(|t| jumping.read(&air, f64::from(t))).collect();
    assert!((r[0] - r[1]).abs() > 20.0 && (r[1] - r[2]).abs() > 20.0);
    // Another cell's sensor is not touched.
    let mut other = AirSensor::new("c2", at, &fault(SensorFaultKind::NotANumber), 1);
    assert!(other.read(&air, 20.0).is_finite());
}

#[test]
fn out_of_range_settings_are_refused_by_name() {
    let bad = AirSensors {
        rate_hz: -1.0,
        ..AirSensors::typical()
    };
    assert_eq!(bad.check().unwrap_err().0, "air_sensors.rate_hz");
    assert!(AirSensors::typical().check().is_ok());
    assert!(AirSensors::default().is_absent());
}

use super::*;
use crate::schedule::{compute_schedule, compute_uniform_schedule, update_rate_hz};

fn all_cells(site: &Site) -> Vec<String> {
    site.cells.iter().map(|c| c.id.clone()).collect()
}

/// Every conflicting pair keeps its spacing, within the cycle and into the next.
fn assert_spacings_kept(table: &SpacingTable, p: &Packing) {
    assert_spacings_kept_under(table, &table.need, p);
}

/// Every pair conflicting under `need` keeps its spacing, within the cycle and into the next.
fn assert_spacings_kept_under(table: &SpacingTable, need: &NeedMatrix, p: &Packing) {
    for &(i, ti) in &p.offsets {
        assert!(
            ti < p.period,
            "offset {ti:?} beyond the period {:?}",
            p.period
        );
        for &(j, tj) in &p.offsets {
            let Some(n) = need_of(need, i, j) else {
                continue;
            };
            // j after i, in this cycle or the next.
            let gap = if tj > ti || (tj == ti && i != j) {
                tj - ti
            } else {
                tj + p.period - ti
            };
            if i != j && tj == ti {
                panic!(
                    "{} and {} conflict and fire together",
                    table.tx_ids[i], table.tx_ids[j]
                );
            }
            assert!(
                gap >= n,
                "{} -> {}: {gap:?} < {n:?}",
                table.tx_ids[i],
                table.tx_ids[j]
            );
        }
    }
}

#[test]
fn packed_sites_keep_every_spacing_within_and_across_cycles() {
    for name in ["lab", "warehouse"] {
        let (site, _) = Site::builtin(name).unwrap();
        let table = SpacingTable::new(&site, &all_cells(&site));
        let p = table.pack_all();
        assert_eq!(p.offsets.len(), site.transmitters.len());
        assert_spacings_kept(&table, &p);
        // A subset too.
        let some: Vec<usize> = (0..table.tx_ids.len()).step_by(3).collect();
        assert_spacings_kept(&table, &table.pack(&some));
    }
}

#[test]
fn spacing_is_the_fixed_part_plus_at_most_the_distance_between_the_transmitters() {
    let site = Site::default_site();
    let table = SpacingTable::new(&site, &all_cells(&site));
    let fixed = site.burst_length_s + site.decoder_window_s + site.guard_time_s;
    let mut conflicts = 0;
    for i in 0..table.tx_ids.len() {
        for j in 0..table.tx_ids.len() {
            let Some(n) = table.need(i, j) else { continue };
            conflicts += 1;
            let a = site.transmitter(table.tx_ids[i]).unwrap().position_m;
            let b = site.transmitter(table.tx_ids[j]).unwrap().position_m;
            let apart_s = distance3(a, b) / site.speed_of_sound_m_s;
            let n = n.as_secs_f64();
            assert!(
                n >= fixed - 1e-9 && n <= fixed + apart_s + 1e-6,
                "{n} {apart_s}"
            );
        }
    }
    // Corridor and room transmitters far apart do not conflict.
    let c1 = table.index_of(11).unwrap();
    let c4 = table.index_of(44).unwrap();
    assert!(table.need(c1, c4).is_none());
    assert!(conflicts > 16);
}

#[test]
fn the_tight_schedule_is_faster_than_the_uniform_one_on_both_sites() {
    for (name, at_least) in [("lab", 1.3), ("warehouse", 1.3)] {
        let (site, _) = Site::builtin(name).unwrap();
        let tight = compute_schedule(&site, &all_cells(&site), 1, 0).unwrap();
        let uniform = compute_uniform_schedule(&site, &all_cells(&site), 1, 0).unwrap();
        let (t, u) = (update_rate_hz(&tight), update_rate_hz(&uniform));
        assert!(
            t >= at_least * u,
            "{name}: tight {t:.2} Hz, uniform {u:.2} Hz"
        );
        assert_eq!(tight.emissions.len(), uniform.emissions.len());
    }
}

#[test]
fn transmitters_on_different_channels_may_fire_together() {
    let text = ickon_proto::site::DEFAULT_SITE_TOML
        .replace("channels = 1", "channels = 2")
        .replace(
            "id = 12\ncell = \"c1\"",
            "id = 12\ncell = \"c1\"\nchannel = 1",
        );
    let site = Site::from_toml(&text, "two-channels.toml").unwrap();
    assert_eq!(site.transmitter(12).unwrap().channel, 1);
    let table = SpacingTable::new(&site, &all_cells(&site));
    let (a, b) = (table.index_of(11).unwrap(), table.index_of(12).unwrap());
    assert!(table.need(a, b).is_none() && table.need(b, a).is_none());
    let p = table.pack(&[a, b]);
    assert_eq!(p.offsets[0].1, p.offsets[1].1);
    let one = SpacingTable::new(&Site::default_site(), &all_cells(&site));
    assert!(one.need(a, b).is_some());
    assert!(one.pack(&[a, b]).period > p.period);
}

#[test]
fn unknown_and_repeated_indices_are_ignored() {
    let site = Site::default_site();
    let table = SpacingTable::new(&site, &all_cells(&site));
    let p = table.pack(&[0, 0, 999, 1]);
    assert_eq!(p.offsets.len(), 2);
    assert_eq!(table.pack(&[]).period, Duration::ZERO);
}

/// The transmitters audible within 8.5 m of the floor within 1.5 m of
/// each of `robots`, and the spacings those points need.
fn occupied(table: &SpacingTable, robots: &[[f64; 2]]) -> (Vec<usize>, NeedMatrix) {
    let mut region: Vec<usize> = robots
        .iter()
        .flat_map(|&c| table.points_within(c, 1.5))
        .collect();
    region.sort_unstable();
    region.dedup();
    let mut set: Vec<usize> = region
        .iter()
        .flat_map(|&p| table.heard_at(p).iter())
        .filter(|&&(_, d)| d <= 8.5)
        .map(|&(k, _)| k)
        .collect();
    set.sort_unstable();
    set.dedup();
    (set, table.needs_over(region.into_iter()))
}

/// The greedy ranking alone, as the packer placed it before the sweeps.
fn greedy_only(table: &SpacingTable, set: &[usize], need: &NeedMatrix) -> Packing {
    let n = |i: usize, j: usize| need_of(need, i, j);
    assert!(set.iter().all(|&i| i < table.tx_ids.len()));
    place(&greedy_ranking(set, &n, &|_| 0.0), &n, None).unwrap()
}

#[test]
fn sweeping_the_floor_never_lengthens_a_cycle_and_shortens_a_fleets() {
    let (site, _) = Site::builtin("warehouse").unwrap();
    let table = SpacingTable::new(&site, &all_cells(&site));
    // Robots in the four aisles (y = 1.5, 5.7, 9.9, 14.1 m) and between them.
    let aisles = [1.5, 5.7, 9.9, 14.1];
    let fleets: Vec<Vec<[f64; 2]>> = vec![
        vec![[20.0, 1.5]],
        vec![[5.0, 1.5], [35.0, 14.1]],
        aisles.iter().map(|&y| [8.0 + 6.0 * y, y]).collect(),
        aisles
            .iter()
            .flat_map(|&y| [[4.0, y], [16.0, y], [28.0, y], [38.0, y]])
            .collect(),
    ];
    let mut shorter = 0;
    for robots in &fleets {
        let (set, need) = occupied(&table, robots);
        let packed = table.pack_with(&set, &need, &|_| 0.0);
        let greedy = greedy_only(&table, &set, &need);
        assert_eq!(packed.offsets.len(), set.len());
        assert_spacings_kept_under(&table, &need, &packed);
        assert!(
            packed.period <= greedy.period,
            "{robots:?}: {:?} > {:?}",
            packed.period,
            greedy.period
        );
        if packed.period < greedy.period {
            shorter += 1;
        }
    }
    assert!(shorter >= 1, "no fleet's cycle got shorter");
    // The whole warehouse: the sweeps keep every spacing across the floor too.
    assert_spacings_kept(&table, &table.pack_all());
}

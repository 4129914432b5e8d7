//! The text tables of `ickon eval` (the ICKON paper's Tables 1-2, the iGPS paper's Table 1).

use std::time::Duration;

use ickon_sim::{Row, Score};

fn line(label: &str, r: &Row) -> String {
    format!(
        "{label:>5} {:8.1} {:8.1} {:6.1} {:6.1} {:7.1} {:8.1} {:8.2} {:8.2} {:8.2}",
        r.mean_mm,
        r.std_mm,
        r.under_30,
        r.under_60,
        r.under_100,
        r.rmse_mm,
        r.heading_mean_deg,
        r.heading_std_deg,
        r.heading_max_deg
    )
}

/// Prints one table per estimator and route, then the summary of the means.
pub fn print(scores: &[&Score], profile: &str, seed: u64, wall: Duration) {
    for s in scores {
        println!(
            "\n{} on {} (profile {profile}, seed {seed})",
            s.estimator, s.route
        );
        println!(
            " tour  mean_mm   std_mm  <30mm  <60mm  <100mm  rmse_mm head_avg head_std head_max"
        );
        for r in &s.tours {
            println!("{}", line(&r.tour.unwrap_or(0).to_string(), r));
        }
        println!("{}", line("mean", &s.mean));
        let mut extra = Vec::new();
        if let Some(v) = s.fix_mean_mm {
            extra.push(format!("fix_mean_mm {v:.2}"));
        }
        if let Some(v) = s.fix_rmse_mm {
            extra.push(format!("fix_rmse_mm {v:.2}"));
        }
        if let (Some(hz), Some(ms)) = (s.fix_rate_hz, s.fix_latency_ms) {
            extra.push(format!("fixes {hz:.2} Hz, latency {ms:.0} ms"));
        }
        if let (Some(sd), Some(mx)) = (s.fix_heading_std_deg, s.fix_heading_max_deg) {
            extra.push(format!("fix heading std {sd:.2} deg, max {mx:.1} deg"));
        }
        if let (Some(r), Some(c)) = (s.crlb_ratio, s.crlb_mm) {
            extra.push(format!("mean/CRLB {r:.2} (CRLB {c:.1} mm)"));
        }
        if let Some(v) = s.inside_95_pct {
            extra.push(format!("truth inside the 95 % ellipse {v:.0} %"));
        }
        if let Some(n) = s.nees {
            extra.push(format!(
                "NEES {:.2} (95 % bounds {:.2}-{:.2} for {} points{})",
                n.mean,
                n.low,
                n.high,
                n.samples,
                if n.consistent() { "" } else { ": inconsistent" }
            ));
        }
        if !extra.is_empty() {
            println!("      {}", extra.join(", "));
        }
    }
    println!("\nsummary: mean error mm (share under 100 mm %) [heading std deg]");
    let mut routes: Vec<&str> = Vec::new();
    for s in scores {
        if !routes.contains(&s.route.as_str()) {
            routes.push(&s.route);
        }
    }
    print!("{:>10}", "");
    for r in &routes {
        print!(" {r:>22}");
    }
    println!();
    let mut names: Vec<&str> = Vec::new();
    for s in scores {
        if !names.contains(&s.estimator.as_str()) {
            names.push(&s.estimator);
        }
    }
    for n in names {
        print!("{n:>10}");
        for r in &routes {
            match scores.iter().find(|s| s.estimator == n && s.route == *r) {
                Some(s) => print!(
                    " {:>22}",
                    format!(
                        "{:.1} ({:.0}) [{:.2}]",
                        s.mean.mean_mm, s.mean.under_100, s.mean.heading_std_deg
                    )
                ),
                None => print!(" {:>22}", "-"),
            }
        }
        println!();
    }
    println!("\nwall time {:.1} s", wall.as_secs_f64());
}

/// Prints each route's cell synchronisation, from the cells' own cores.
pub fn print_cells(outputs: &[ickon_sim::RunOutput]) {
    println!("\ncell sync (actual - scheduled emission, from the cells' own synchronisation)");
    for o in outputs {
        let cells: Vec<String> = o
            .cells
            .iter()
            .map(|c| {
                format!(
                    "{} max {:.0} us rms {:.0} us ({} bursts, {} skipped)",
                    c.cell_id,
                    c.sync_error_max_us,
                    c.sync_error_rms_us,
                    c.bursts,
                    c.counters.slots_skipped
                )
            })
            .collect();
        println!("  {:>9}: {}", o.config.route, cells.join("; "));
    }
    println!(
        "\nschedule and channel (cycles/s of the schedule; detections lost to collisions and reverberation)"
    );
    for o in outputs {
        let c = &o.collisions;
        println!(
            "  {:>9}: {:.2} cycles/s, {} fixes/s; {} detections, {} collided ({} misdecoded), {} masked: {:.2} % lost",
            o.config.route,
            ickon_central::update_rate_hz(&o.schedule),
            fmt_rate(o.fixes.len(), o.virtual_s),
            c.detected,
            c.collided,
            c.misdecoded,
            c.masked,
            100.0 * c.lost_share()
        );
    }
}

/// `count` per second of `seconds`, two decimals (`-` for no time).
fn fmt_rate(count: usize, seconds: f64) -> String {
    if seconds > 0.0 {
        format!("{:.2}", count as f64 / seconds)
    } else {
        "-".into()
    }
}

/// The worst error of the speed used after the first minute, in words.
pub(crate) fn worst_after_first_minute(pct: Option<f64>) -> String {
    match pct {
        Some(p) => format!("{p:.3} % at worst after it"),
        None => "nothing after it to judge (the run is a minute or shorter)".to_string(),
    }
}

/// The speed of sound the MSU used against the air's, per route.
pub fn print_air(outputs: &[ickon_sim::RunOutput], site_m_s: f64) {
    println!(
        "\nspeed of sound (the MSU's against the true average of the paths within {} m)",
        ickon_sim::engine::AIR_PATHS_M
    );
    for o in outputs {
        match ickon_sim::score::AirScore::of(&o.air, site_m_s) {
            Some(a) => println!(
                "{:>11}: used {:.3} % off on average ({:.3} % in the first minute), {} (the site \
                 file's {:.3} % off); the air {:.1}-{:.1} m/s",
                o.config.route,
                a.used_mean_pct,
                a.first_minute_mean_pct,
                worst_after_first_minute(a.used_max_pct),
                a.site_mean_pct,
                a.true_range_m_s[0],
                a.true_range_m_s[1]
            ),
            None => println!("{:>11}: no transmitter near the robot", o.config.route),
        }
    }
}

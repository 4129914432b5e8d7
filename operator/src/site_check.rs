//! `ickon site check`: validate a site file and print what it describes.

use std::path::Path;

use ickon_proto::site::Site;

use ickon_runtime::CommandError;

/// Validates a site (a built-in name or a file; the built-in `lab` when
/// `file` is `None`) and prints its summary on stdout; every problem goes to
/// stderr with exit code 2.
pub fn check(file: Option<&Path>) -> Result<(), CommandError> {
    let (site, _, name) =
        Site::load_or_default(file).map_err(|e| CommandError::bad_input(e.to_string()))?;
    print!("{}", summary(&site, &name));
    Ok(())
}

/// A human-readable summary of a valid site.
pub fn summary(site: &Site, file: &str) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let temperature = site
        .temperature_c
        .map(|t| format!(" ({t} degC)"))
        .unwrap_or_default();
    let _ = writeln!(out, "site {:?} from {file}: valid", site.name);
    let _ = writeln!(
        out,
        "  floor area {:.1} m2 in {} cells, {} transmitters, {} walls, {} columns",
        site.area_m2(),
        site.cells.len(),
        site.transmitters.len(),
        site.walls.len(),
        site.columns.len()
    );
    let _ = writeln!(
        out,
        "  speed of sound {:.2} m/s{temperature}, guard time {:.1} ms, ceiling {:.2} m",
        site.speed_of_sound_m_s,
        site.guard_time_s * 1e3,
        site.ceiling_height_m
    );
    let _ = writeln!(
        out,
        "  MSU: {} receivers at {:.2} m",
        site.msu.receiver_angles_rad.len(),
        site.msu.height_m
    );
    let _ = writeln!(out, "cells:");
    for cell in &site.cells {
        let ids: Vec<String> = site
            .transmitters_of(&cell.id)
            .map(|t| t.id.to_string())
            .collect();
        let _ = writeln!(
            out,
            "  {:<8} {:>6.1} m2  transmitters {}",
            cell.id,
            cell.area_m2(),
            ids.join(", ")
        );
    }
    let _ = writeln!(out, "routes:");
    for route in &site.routes {
        let length = route.length_m();
        let _ = writeln!(
            out,
            "  {:<10} {:>6.1} m {:<6}  {:>3} reference points  {:.2} m/s  ({:.0} s per tour)",
            route.name,
            length,
            if route.closed { "loop" } else { "open" },
            route.reference_points.len(),
            route.speed_m_s,
            length / route.speed_m_s
        );
    }
    let _ = writeln!(out, "robots:");
    for robot in &site.robots {
        let _ = writeln!(
            out,
            "  {:<8} on {:<10} start ({:.2}, {:.2}) heading {:.0} deg",
            robot.id,
            // A real site's robot drives no route.
            if robot.route.is_empty() {
                "no route"
            } else {
                &robot.route
            },
            robot.start[0],
            robot.start[1],
            robot.start[2].to_degrees()
        );
    }
    out
}

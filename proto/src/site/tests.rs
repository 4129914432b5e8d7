//! The built-in site, and one test for each kind of breakage a user might make.

use super::*;

fn issues_of(text: &str) -> Vec<SiteIssue> {
    match Site::from_toml(text, "test.toml") {
        Ok(_) => panic!("broken site accepted"),
        Err(SiteError::Invalid { issues, .. }) => issues,
        Err(e) => panic!("unexpected error {e}"),
    }
}

/// The default site with one textual replacement applied (which must match).
fn broken(from: &str, to: &str) -> String {
    assert!(DEFAULT_SITE_TOML.contains(from), "{from:?} not in lab.toml");
    DEFAULT_SITE_TOML.replacen(from, to, 1)
}

fn line_of(text: &str, needle: &str) -> usize {
    text[..text.find(needle).expect("needle")]
        .matches('\n')
        .count()
        + 1
}

#[test]
fn built_in_site_is_valid_and_as_documented() {
    let site = Site::default_site();
    assert_eq!(site.name, "lab");
    assert_eq!(site.cells.len(), 4);
    assert_eq!(site.transmitters.len(), 16);
    for cell in &site.cells {
        assert!((cell.area_m2() - 20.0).abs() < 1e-9, "{} area", cell.id);
        assert_eq!(site.transmitters_of(&cell.id).count(), 4);
    }
    for name in ["route-1", "route-2", "rectangle", "eight", "random"] {
        let route = site.route(name).expect(name);
        assert_eq!(route.reference_points.len(), 60, "{name}");
    }
    for name in ["route-1", "route-2"] {
        let route = site.route(name).unwrap();
        let cells: std::collections::HashSet<_> = route
            .reference_points
            .iter()
            .filter_map(|p| site.cell_at(*p).map(|c| c.id.clone()))
            .collect();
        assert_eq!(cells.len(), 4, "{name} must cross all four cells");
    }
    assert!((site.speed_of_sound_m_s - 343.2).abs() < 0.1);
    assert_eq!(site.msu.receiver_angles_rad.len(), 6);
}

#[test]
fn speed_of_sound_follows_temperature() {
    assert!((speed_of_sound_at(0.0) - 331.3).abs() < 1e-9);
    assert!((speed_of_sound_at(20.0) - 343.21).abs() < 0.01);
}

#[test]
fn syntax_error_names_its_line() {
    let text = broken("receivers = 6", "receivers = = 6");
    let issues = issues_of(&text);
    assert_eq!(issues[0].line, line_of(&text, "receivers = = 6"));
    assert_eq!(issues[0].field, "(syntax)");
}

#[test]
fn misspelt_field_is_refused_by_name() {
    let text = broken("position = [1.2, 0.6, 2.80]", "postion = [1.2, 0.6, 2.80]");
    let issues = issues_of(&text);
    assert_eq!(issues.len(), 1);
    assert!(issues[0].message.contains("postion"), "{:?}", issues[0]);
    assert_eq!(issues[0].line, line_of(&text, "postion"));
}

#[test]
fn wrong_type_is_refused() {
    let issues = issues_of(&broken("height_m = 0.5", "height_m = \"half a metre\""));
    assert!(issues[0].message.contains("float") || issues[0].message.contains("invalid type"));
}

#[test]
fn duplicate_transmitter_id_is_reported_with_both_places() {
    let text = broken("id = 12\n", "id = 11\n");
    let issues = issues_of(&text);
    let dup = issues
        .iter()
        .find(|i| i.message.contains("duplicate transmitter id 11"))
        .expect("duplicate reported");
    assert_eq!(dup.field, "transmitters[1].id");
    assert!(dup.message.contains("transmitters[0]"));
}

#[test]
fn duplicate_cell_and_robot_ids_are_reported() {
    let text = broken("id = \"c2\"", "id = \"c1\"");
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("duplicate cell id"))
    );
    let text = broken("id = \"r2\"", "id = \"r1\"");
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("duplicate robot id"))
    );
}

#[test]
fn transmitter_outside_its_cell_is_reported_at_its_line() {
    let text = broken("position = [6.8, 0.6, 2.65]", "position = [9.8, 0.6, 2.65]");
    let issues = issues_of(&text);
    let i = issues
        .iter()
        .find(|i| i.message.contains("outside its cell"))
        .unwrap();
    assert_eq!(i.line, line_of(&text, "[9.8, 0.6, 2.65]"));
    assert_eq!(i.field, "transmitters[1].position");
}

#[test]
fn cell_with_too_few_transmitters_is_reported() {
    // Move transmitter 44 into cell c3: c4 keeps three (fine), then 43 too: c4 has two.
    let text = broken(
        "id = 43\ncell = \"c4\"\nposition = [20.2, 7.3, 2.80]",
        "id = 43\ncell = \"c3\"\nposition = [20.2, 3.0, 2.80]",
    );
    let text = text.replacen(
        "id = 44\ncell = \"c4\"\nposition = [16.8, 7.3, 2.65]",
        "id = 44\ncell = \"c3\"\nposition = [17.5, 3.0, 2.65]",
        1,
    );
    let issues = issues_of(&text);
    assert!(
        issues
            .iter()
            .any(|i| i.message.contains("cell \"c4\" has 2 transmitters")),
        "{issues:?}"
    );
}

#[test]
fn transmitter_inside_a_wall_or_column_is_reported() {
    let text = broken(
        "position = [6.8, 1.9, 2.80]",
        "position = [6.8, 2.48, 2.80]",
    );
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("inside walls[1]"))
    );
    let text = broken(
        "position = [20.2, 3.3, 2.80]",
        "position = [18.5, 3.9, 2.80]",
    );
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("inside columns[1]"))
    );
}

#[test]
fn empty_route_and_unknown_route_are_reported() {
    let text = broken(
        "points = [[16.8, 1.0], [20.2, 1.0], [20.2, 3.2], [16.8, 3.2]]",
        "points = []",
    );
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("at least 2 points"))
    );
    let text = broken("route = \"eight\"", "route = \"figure-8\"");
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("no route named"))
    );
}

#[test]
fn route_through_a_wall_is_reported() {
    let text = broken("[16.8, 1.0], [20.2, 1.0]", "[14.8, 3.0], [20.2, 1.0]");
    let issues = issues_of(&text);
    assert!(
        issues
            .iter()
            .any(|i| i.message.contains("outside every cell") || i.message.contains("wall")),
        "{issues:?}"
    );
}

#[test]
fn non_finite_numbers_are_reported() {
    let text = broken("position = [1.2, 0.6, 2.80]", "position = [nan, 0.6, 2.80]");
    assert!(
        issues_of(&text)
            .iter()
            .any(|i| i.message.contains("finite"))
    );
    let text = broken("temperature_c = 20.0", "temperature_c = inf");
    assert!(issues_of(&text).iter().any(|i| i.field == "temperature_c"));
}

#[test]
fn every_problem_is_reported_at_once() {
    let text = broken("id = 12\n", "id = 11\n");
    let text = text.replacen("height_m = 0.5", "height_m = -1.0", 1);
    let text = text.replacen("route = \"eight\"", "route = \"nope\"", 1);
    let issues = issues_of(&text);
    assert!(issues.len() >= 3, "{issues:?}");
    let lines: Vec<usize> = issues.iter().map(|i| i.line).collect();
    let mut sorted = lines.clone();
    sorted.sort();
    assert_eq!(lines, sorted, "issues come in file order");
}

#[test]
fn error_text_names_file_line_and_field() {
    let text = broken("temperature_c = 20.0", "temperature_c = 99.0");
    let err = Site::from_toml(&text, "site.toml").unwrap_err().to_string();
    let line = line_of(&text, "temperature_c = 99.0");
    assert!(err.contains(&format!("site.toml:{line}:")), "{err}");
    assert!(err.contains("temperature_c"), "{err}");
}

#[test]
fn missing_file_is_an_io_error() {
    let err = Site::from_file(std::path::Path::new("/nonexistent/site.toml")).unwrap_err();
    assert!(matches!(err, SiteError::Io { .. }));
}

#[test]
fn line_of_sight_is_blocked_by_walls_but_not_over_them() {
    let site = Site::default_site();
    // Corridor transmitter to a room point behind the wall: blocked.
    let tx = site.transmitter(22).unwrap().position_m;
    assert!(!site.line_of_sight(tx, [18.0, 6.0, 0.5]));
    // Same cell: clear.
    assert!(site.line_of_sight(tx, [13.0, 1.0, 0.5]));
    // A low wall would not block a line passing above it.
    let mut low = site.clone();
    for w in &mut low.walls {
        w.height_m = 0.1;
    }
    low.columns.clear();
    assert!(low.line_of_sight(tx, [18.0, 6.0, 0.5]));
}

#[test]
fn carrier_channels_default_to_one_and_a_transmitter_may_not_use_more_than_the_msu_hears() {
    let site = Site::default_site();
    assert_eq!(site.msu.channels, 1);
    assert!(site.transmitters.iter().all(|t| t.channel == 0));
    assert!((site.burst_length_s - 0.002).abs() < 1e-12);
    assert!((site.decoder_window_s - 0.0005).abs() < 1e-12);

    let text = broken(
        "id = 12\ncell = \"c1\"",
        "id = 12\ncell = \"c1\"\nchannel = 1",
    );
    let issues = issues_of(&text);
    assert_eq!(issues.len(), 1, "{issues:?}");
    assert_eq!(issues[0].field, "transmitters[1].channel");
    assert_eq!(issues[0].line, line_of(&text, "channel = 1"));
    assert!(
        issues[0].message.contains("declares 1 channel"),
        "{}",
        issues[0].message
    );

    let two = text.replace("channels = 1", "channels = 2");
    let site = Site::from_toml(&two, "two.toml").unwrap();
    assert_eq!(site.msu.channels, 2);
    assert_eq!(site.transmitter(12).unwrap().channel, 1);

    for bad in ["channels = 0", "channels = 17", "channels = -3"] {
        let issues = issues_of(&broken("channels = 1", bad));
        assert_eq!(issues[0].field, "msu.channels", "{bad}");
    }
    let issues = issues_of(&broken(
        "id = 12\ncell = \"c1\"",
        "id = 12\ncell = \"c1\"\nchannel = -1",
    ));
    assert_eq!(issues[0].field, "transmitters[1].channel");
    let issues = issues_of(&broken("burst_length_ms = 2.0", "burst_length_ms = -2.0"));
    assert_eq!(issues[0].field, "burst_length_ms");
}

#[test]
fn a_real_sites_robot_needs_no_route_but_a_start() {
    let real = broken(
        "id = \"r1\"\nroute = \"route-1\"",
        "id = \"r1\"\nstart = [2.0, 1.2, 90.0]",
    );
    let site = Site::from_toml(&real, "test.toml").expect("a robot without a route");
    let r1 = site.robots.iter().find(|r| r.id == "r1").unwrap();
    assert_eq!(r1.route, "");
    assert_eq!([r1.start[0], r1.start[1]], [2.0, 1.2]);

    let nowhere = broken("id = \"r1\"\nroute = \"route-1\"", "id = \"r1\"");
    let issues = issues_of(&nowhere);
    assert_eq!(issues.len(), 1, "{issues:?}");
    assert_eq!(issues[0].field, "robots[0].start");
    assert!(issues[0].message.contains("without a route"), "{issues:?}");
}

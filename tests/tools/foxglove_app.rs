//! Foxglove Studio's own app (`@foxglove/studio-base`, the code of the
//! Foxglove Studio 1.x desktop and web app) opened on `ickon sim
//! --foxglove` in headless Chromium, with the lab's shipped layout
//! (`deploy/foxglove/lab.json`): the app lists the site's topics, and its
//! 3D panel draws the cells and the robots, read from the screenshot's
//! pixels. The app asks for the protocol's older subprotocol name
//! (`foxglove.websocket.v1`), so this is also the server's front door
//! meeting a client it was written for.
//!
//! It needs the page of `tests/foxglove-app/` built (`npm ci && npm run
//! build` there) and a browser; without either it skips, said in one line.
//! `ICKON_FOXGLOVE_APP=DIR` names a built page that must be there.
//! `ICKON_FOXGLOVE_SCREENSHOT=FILE` keeps the picture (docs/foxglove.md's).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use ickon_testkit::{ChildGuard, free_tcp_port, poll_until};
use serde_json::Value;
use support::ICKON;
use support::browser::{Browser, chromium_or_skip};
use support::static_http;

/// Generous but bounded: a loaded two-core machine starts nine processes
/// slowly, and the app's 27 MB script takes a while to compile.
const START_TIMEOUT: Duration = Duration::from_secs(120);
/// The topics the app must list: the site, the cells, every robot's.
const TOPICS: [&str; 7] = [
    "/site/scene",
    "/site/cells",
    "/robots/scene",
    "/tf",
    "/robot/r1/pose",
    "/robot/r2/pose",
    "/robot/r3/pose",
];

/// Pixels of a tracking robot's blue that say robots are drawn: an arrow
/// of the lab's three robots is about 16 x 5 pixels at the layout's zoom,
/// and its label as many again; fewer than this is less than one robot.
const MIN_ROBOT_PX: usize = 30;
/// Pixels of a firing cell's green that say the cells are drawn: the lab's
/// four outlines are over 1,500 pixels long; this is one short side's worth.
const MIN_CELL_PX: usize = 200;

/// `ICKON_FOXGLOVE_SCREENSHOT=FILE` keeps `png` there.
fn keep_screenshot(png: &[u8]) {
    if let Some(path) = std::env::var_os("ICKON_FOXGLOVE_SCREENSHOT") {
        std::fs::write(path, png).expect("screenshot written");
    }
}

/// The built page, or `None` (skipped, said in one line). A page named by
/// `ICKON_FOXGLOVE_APP` must be there.
fn built_page() -> Option<PathBuf> {
    let named = std::env::var_os("ICKON_FOXGLOVE_APP").filter(|v| !v.is_empty());
    let dir = named.clone().map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("foxglove-app/dist"),
        PathBuf::from,
    );
    if dir.join("index.html").exists() && dir.join("app.js").exists() {
        return Some(dir);
    }
    assert!(
        named.is_none(),
        "ICKON_FOXGLOVE_APP names {}, which holds no built page",
        dir.display()
    );
    eprintln!(
        "skipped: Foxglove Studio's page is not built at {} (npm ci && npm run build in tests/foxglove-app)",
        dir.display()
    );
    None
}

fn start_sim(dir: &Path, port: u16) -> ChildGuard {
    let mut cmd = Command::new(ICKON);
    cmd.args(["sim", "--robots", "3", "--duration", "180", "--seed", "1"])
        .arg("--foxglove")
        .arg(format!("127.0.0.1:{port}"))
        .env("XDG_RUNTIME_DIR", dir);
    ChildGuard::spawn("sim", cmd, dir).expect("ickon sim starts")
}

/// The text of the app's topic list (the data source sidebar's Topics tab,
/// opened first).
const TOPIC_LIST: &str = r#"(() => {
  const tab = [...document.querySelectorAll('[role=tab]')].find(t => t.textContent.trim() === 'Topics');
  if (tab && tab.getAttribute('aria-selected') !== 'true') tab.click();
  return document.body ? document.body.innerText : "";
})()"#;

/// Dismisses the 3D panel's first-visit hint, which covers the view.
const DISMISS_HINT: &str = r#"(() => { const b = document.querySelector('.MuiTooltip-tooltip button[aria-label=Dismiss]'); if (b) b.click(); return !!b; })()"#;

/// The 3D panel's canvas, in CSS pixels of the page.
const CANVAS_RECT: &str = r#"(() => {
  const c = document.querySelector('canvas[data-engine^="three.js"]');
  if (!c) return null;
  const r = c.getBoundingClientRect();
  return {x: r.x, y: r.y, w: r.width, h: r.height, dpr: window.devicePixelRatio};
})()"#;

/// Pixels of the 3D panel by what they show.
#[derive(Debug, Default, PartialEq)]
struct Drawn {
    /// A tracking robot's arrow and ellipse (blue).
    robots: usize,
    /// A cell's outline while it fires (green).
    cells: usize,
}

/// Counts, inside `rect` of the PNG, the pixels of a tracking robot's blue
/// (0.1, 0.45, 0.85) and of a firing cell's green (0.18, 0.62, 0.28), with
/// room for the panel's lighting and antialiasing.
fn count_drawn(png: &[u8], rect: &Value) -> Drawn {
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG frame");
    let channels = info.color_type.samples();
    let scale = rect["dpr"].as_f64().unwrap_or(1.0);
    let at = |k: &str| (rect[k].as_f64().unwrap_or(0.0) * scale) as u32;
    let (x0, y0) = (at("x"), at("y"));
    let (x1, y1) = (
        (x0 + at("w")).min(info.width),
        (y0 + at("h")).min(info.height),
    );
    let mut drawn = Drawn::default();
    for y in y0..y1 {
        for x in x0..x1 {
            let i = (y as usize * info.width as usize + x as usize) * channels;
            let (r, g, b) = (
                i32::from(buf[i]),
                i32::from(buf[i + 1]),
                i32::from(buf[i + 2]),
            );
            // The routes' paler blue (0.3, 0.45, 0.9 at 60 %) is left out by red.
            if r < 80 && b > 150 && b > g + 50 {
                drawn.robots += 1;
            } else if g > 110 && g > r + 60 && g > b + 50 {
                drawn.cells += 1;
            }
        }
    }
    drawn
}

#[test]
fn foxglove_studio_lists_the_topics_and_draws_the_site_and_the_robots() {
    let Some(chromium) = chromium_or_skip() else {
        return;
    };
    let Some(page) = built_page() else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let mut sim = start_sim(dir.path(), free_tcp_port().expect("port"));
    let ws: String = poll_until(START_TIMEOUT, "the Foxglove address printed", || {
        if let Some(status) = sim.exit_status() {
            panic!("ickon sim {status}:\n{}", sim.log());
        }
        let log = sim.log();
        let at = log.split("Foxglove live server at ws://").nth(1)?;
        Some(at.split_whitespace().next()?.to_string())
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", sim.log()));

    let layouts = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/foxglove");
    let http = static_http::serve(vec![
        ("/layouts/".to_string(), layouts),
        ("/".to_string(), page),
    ])
    .expect("static server");
    let mut browser = Browser::launch(&chromium, &dir.path().join("browser"));
    // Room for the 3D panel beside the plots, as on a desktop screen.
    browser.page(
        "Emulation.setDeviceMetricsOverride",
        serde_json::json!({"width": 1600, "height": 1000, "deviceScaleFactor": 1, "mobile": false}),
    );
    browser.navigate(&format!(
        "http://127.0.0.1:{http}/index.html?ds=foxglove-websocket&ds.url=ws://{ws}&layoutId=lab"
    ));

    // The app lists the site's topics: it connected and read the channels.
    let listed = poll_until(START_TIMEOUT, "the app's topic list", || {
        let text = browser.eval(TOPIC_LIST);
        let text = text.as_str()?;
        TOPICS
            .iter()
            .all(|t| text.contains(t))
            .then(|| text.to_string())
    });
    if let Err(e) = listed {
        let text = browser.eval(TOPIC_LIST);
        panic!(
            "{e}: the page says\n{}\nbrowser errors: {:?}",
            text.as_str().unwrap_or_default(),
            browser.errors
        );
    }

    // The 3D panel draws the cells (firing: green) and the robots (tracking:
    // blue), in pixels of a screenshot, not only in messages received.
    let mut last = (Vec::new(), Drawn::default());
    let seen = poll_until(Duration::from_secs(60), "robots and cells drawn", || {
        browser.eval(DISMISS_HINT);
        let rect = browser.eval(CANVAS_RECT);
        if rect.is_null() {
            return None;
        }
        let png = browser.screenshot();
        let drawn = count_drawn(&png, &rect);
        let enough = drawn.robots >= MIN_ROBOT_PX && drawn.cells >= MIN_CELL_PX;
        last = (png, drawn);
        enough.then_some(())
    });
    if let Err(e) = seen {
        keep_screenshot(&last.0);
        panic!(
            "{e}: the 3D panel shows {:?}\nbrowser errors: {:?}\nsim: {}",
            last.1,
            browser.errors,
            sim.log_tail(20)
        );
    }
    // Still drawn a while later, with the plots filled in: the picture kept.
    std::thread::sleep(Duration::from_secs(10));
    let rect = browser.eval(CANVAS_RECT);
    let png = browser.screenshot();
    let drawn = count_drawn(&png, &rect);
    keep_screenshot(&png);
    eprintln!("the 3D panel shows {:?}", drawn);
    assert!(
        drawn.robots >= MIN_ROBOT_PX && drawn.cells >= MIN_CELL_PX,
        "10 s later the 3D panel shows {drawn:?}"
    );
    if let Some(status) = sim.exit_status() {
        panic!("ickon sim {status} while the app watched:\n{}", sim.log());
    }
}

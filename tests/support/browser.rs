//! Headless Chromium driven over its DevTools protocol, and a plain HTTP GET,
//! for the web map's tests.
//!
//! The protocol is JSON over one WebSocket: a command is `{id, method,
//! params, sessionId}`, its answer carries the same `id`, anything else is
//! an event. The four commands the tests need are a few lines each, so this
//! is written on `tungstenite` alone rather than on a browser-automation
//! crate (those bring an async runtime or a browser downloader of their own,
//! and launch Chromium with flags the closed network does not tolerate).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use ickon_testkit::{ChildGuard, poll_until};
use serde_json::{Value, json};
use tungstenite::{Message, WebSocket};

/// Where Debian's `chromium` package puts the browser.
pub const CHROMIUM: &str = "/usr/bin/chromium";

/// The browser, or `None` (the test is skipped, said in one line). A
/// browser named by `ICKON_CHROMIUM` must be there: `.ci/run` names the
/// one it installs, so that a missing browser fails there and only there.
pub fn chromium_or_skip() -> Option<PathBuf> {
    let named = std::env::var_os("ICKON_CHROMIUM").filter(|v| !v.is_empty());
    let path = named
        .clone()
        .map_or_else(|| PathBuf::from(CHROMIUM), PathBuf::from);
    if path.exists() {
        return Some(path);
    }
    assert!(
        named.is_none(),
        "ICKON_CHROMIUM names {}, which is missing (.ci/run installs Debian's chromium)",
        path.display()
    );
    eprintln!(
        "skipped: no browser at {} (apt-get install chromium, or set ICKON_CHROMIUM)",
        path.display()
    );
    None
}

/// A plain HTTP/1.1 GET or POST on loopback: status code and body.
pub fn http(
    method: &str,
    port: u16,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> std::io::Result<(u16, String)> {
    let mut s = TcpStream::connect(("127.0.0.1", port))?;
    s.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    req.push_str(body);
    s.write_all(req.as_bytes())?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw)?;
    let text = String::from_utf8_lossy(&raw).into_owned();
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    // Chunked bodies (axum's JSON is not chunked, but be safe): strip sizes.
    let body = if text
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        dechunk(body)
    } else {
        body.to_string()
    };
    Ok((code, body))
}

fn dechunk(mut body: &str) -> String {
    let mut out = String::new();
    while let Some((size, rest)) = body.split_once("\r\n") {
        let Ok(n) = usize::from_str_radix(size.trim(), 16) else {
            break;
        };
        if n == 0 || rest.len() < n {
            break;
        }
        out.push_str(&rest[..n]);
        body = rest[n..].trim_start_matches("\r\n");
    }
    out
}

/// A headless Chromium and one page of it, attached over DevTools.
pub struct Browser {
    _process: ChildGuard,
    ws: WebSocket<TcpStream>,
    next_id: u64,
    session: Option<String>,
    /// Console errors, uncaught exceptions and error log entries seen so far.
    pub errors: Vec<String>,
}

impl Browser {
    /// Starts `chromium` with a fresh profile under `dir` and opens a blank page.
    pub fn launch(chromium: &Path, dir: &Path) -> Self {
        let profile = dir.join("chromium-profile");
        std::fs::create_dir_all(dir).expect("browser dir");
        std::fs::create_dir_all(&profile).expect("profile dir");
        let mut cmd = Command::new(chromium);
        cmd.args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-dev-shm-usage",
            "--remote-debugging-port=0",
            "--window-size=1400,900",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("about:blank");
        let process = ChildGuard::spawn("chromium", cmd, dir).expect("chromium starts");
        // Chromium writes the port it bound and the browser's path here.
        let active = profile.join("DevToolsActivePort");
        let (port, path) = poll_until(Duration::from_secs(60), "DevToolsActivePort", || {
            let text = std::fs::read_to_string(&active).ok()?;
            let mut lines = text.lines();
            let port: u16 = lines.next()?.trim().parse().ok()?;
            Some((port, lines.next()?.trim().to_string()))
        })
        .expect("chromium announces its DevTools port");
        let stream = TcpStream::connect(("127.0.0.1", port)).expect("devtools socket");
        stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .expect("timeout");
        let (ws, _) = tungstenite::client(format!("ws://127.0.0.1:{port}{path}"), stream)
            .expect("devtools handshake");
        let mut browser = Self {
            _process: process,
            ws,
            next_id: 0,
            session: None,
            errors: Vec::new(),
        };
        let target = browser.call(None, "Target.createTarget", json!({"url": "about:blank"}));
        let target_id = target["targetId"].as_str().expect("target id").to_string();
        let attached = browser.call(
            None,
            "Target.attachToTarget",
            json!({"targetId": target_id, "flatten": true}),
        );
        browser.session = attached["sessionId"].as_str().map(str::to_string);
        for domain in ["Runtime.enable", "Log.enable", "Page.enable"] {
            browser.page(domain, json!({}));
        }
        browser
    }

    fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut msg = json!({"id": id, "method": method, "params": params});
        if let Some(s) = session {
            msg["sessionId"] = json!(s);
        }
        self.ws
            .send(Message::text(msg.to_string()))
            .expect("devtools send");
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            let text = match self.ws.read().expect("devtools read") {
                Message::Text(t) => t.to_string(),
                _ => continue,
            };
            let v: Value = serde_json::from_str(&text).expect("devtools json");
            if v["id"] == json!(id) {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
            self.note_event(&v);
        }
        panic!("{method}: no answer within 30 s");
    }

    fn note_event(&mut self, v: &Value) {
        let p = &v["params"];
        match v["method"].as_str() {
            Some("Runtime.exceptionThrown") => self.errors.push(format!("exception: {p}")),
            Some("Runtime.consoleAPICalled") if p["type"] == "error" => {
                self.errors.push(format!("console.error: {}", p["args"]))
            }
            Some("Log.entryAdded") if p["entry"]["level"] == "error" => {
                self.errors.push(format!("log: {}", p["entry"]))
            }
            _ => {}
        }
    }

    /// Opens one more page (a tab, with its own connection) at `url`.
    pub fn open_tab(&mut self, url: &str) {
        self.call(None, "Target.createTarget", json!({"url": url}));
    }

    /// A command to the page.
    pub fn page(&mut self, method: &str, params: Value) -> Value {
        let session = self.session.clone();
        self.call(session.as_deref(), method, params)
    }

    /// Opens `url` in the page.
    pub fn navigate(&mut self, url: &str) {
        self.page("Page.navigate", json!({"url": url}));
    }

    /// Evaluates `expression` in the page; its value (JSON-able).
    pub fn eval(&mut self, expression: &str) -> Value {
        let r = self.page(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true}),
        );
        assert!(r.get("exceptionDetails").is_none(), "{expression}: {r}");
        r["result"]["value"].clone()
    }

    /// A PNG screenshot of the page.
    pub fn screenshot(&mut self) -> Vec<u8> {
        let r = self.page("Page.captureScreenshot", json!({"format": "png"}));
        use base64::Engine;
        base64::engine::general_purpose::STANDARD
            .decode(r["data"].as_str().expect("png data"))
            .expect("base64 png")
    }
}

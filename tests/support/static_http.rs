//! A static file server on loopback for a test's browser: GET only, one
//! thread per connection, files from a few directories each mounted under
//! a URL prefix. A page loaded over `file://` could not fetch its layout nor
//! stream its WebAssembly, which is why the test serves it over HTTP.

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};

/// Serves `mounts` (URL prefix, directory; the first matching prefix wins)
/// on a free loopback port until the test process ends; returns the port.
pub fn serve(mounts: Vec<(String, PathBuf)>) -> std::io::Result<u16> {
    let listener = TcpListener::bind(("127.0.0.1", 0))?;
    let port = listener.local_addr()?.port();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let mounts = mounts.clone();
            std::thread::spawn(move || {
                // A browser dropping a connection is no failure of the test.
                let _ = answer(stream, &mounts);
            });
        }
    });
    Ok(port)
}

fn answer(stream: TcpStream, mounts: &[(String, PathBuf)]) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.read_line(&mut request)?;
    // The headers are read and ignored: every answer closes the connection.
    let mut header = String::new();
    while reader.read_line(&mut header)? > 2 {
        header.clear();
    }
    let target = request.split_whitespace().nth(1).unwrap_or("/");
    let path = target.split(['?', '#']).next().unwrap_or("/");
    let file = resolve(path, mounts);
    let mut out = stream;
    match file.and_then(|f| std::fs::read(&f).ok().map(|body| (f, body))) {
        Some((f, body)) => {
            let head = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                content_type(&f),
                body.len()
            );
            out.write_all(head.as_bytes())?;
            out.write_all(&body)
        }
        None => out
            .write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"),
    }
}

/// The file a URL path names, or `None` for one outside every mount.
fn resolve(path: &str, mounts: &[(String, PathBuf)]) -> Option<PathBuf> {
    let (prefix, dir) = mounts.iter().find(|(p, _)| path.starts_with(p.as_str()))?;
    let rest = &path[prefix.len()..];
    let rest = if rest.is_empty() { "index.html" } else { rest };
    let relative = Path::new(rest.trim_start_matches('/'));
    // Only plain names: no `..`, no absolute path.
    if !relative
        .components()
        .all(|c| matches!(c, Component::Normal(_)))
    {
        return None;
    }
    Some(dir.join(relative))
}

/// WebAssembly must be served as such for the browser to stream it.
fn content_type(file: &Path) -> &'static str {
    match file.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript",
        Some("json") => "application/json",
        Some("wasm") => "application/wasm",
        Some("png") => "image/png",
        Some("ttf") => "font/ttf",
        _ => "application/octet-stream",
    }
}

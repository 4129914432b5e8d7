//! The Foxglove server's public port: a thin TCP relay in front of the
//! SDK's server that also lets in clients asking for the protocol's older
//! name, `foxglove.websocket.v1`.
//!
//! The SDK negotiates only `foxglove.sdk.v1` and `foxglove.sdk.v1.1` and has
//! no option for other names, while Lichtblick and Foxglove Studio 1.x ask
//! for `foxglove.websocket.v1`, the same protocol under its earlier name.
//! The relay reads a connection's HTTP upgrade request, renames the older
//! subprotocol in its `Sec-WebSocket-Protocol` header, hands it to the SDK's
//! server on loopback, renames the agreed subprotocol back in the answer
//! (a browser drops a connection whose agreed subprotocol it did not offer)
//! and from then on copies bytes both ways untouched. The WebSocket accept
//! key depends on the client's key alone, so renaming a header is safe.

use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// The protocol's older name, asked for by Lichtblick and Foxglove Studio 1.x.
pub const LEGACY_SUBPROTOCOL: &str = "foxglove.websocket.v1";

/// The name the SDK negotiates for the same protocol.
const SDK_SUBPROTOCOL: &str = "foxglove.sdk.v1";

/// Every name the SDK accepts by itself.
const SDK_NAMES: [&str; 2] = ["foxglove.sdk.v1", "foxglove.sdk.v1.1"];

/// The longest HTTP head read from either side: an upgrade request is a
/// few hundred bytes; anything longer is not a client of this server.
const MAX_HEAD: usize = 16 * 1024;

/// How long a connection may take to send its upgrade request, so that a
/// client that opens the port and says nothing does not hold a task.
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

/// The header naming the subprotocols.
const PROTOCOL_HEADER: &str = "sec-websocket-protocol";

/// Accepts connections on `listener` and relays each to the SDK's server
/// at `inner`, until the task is aborted.
pub async fn serve(listener: TcpListener, inner: SocketAddr) {
    loop {
        match listener.accept().await {
            Ok((client, _)) => {
                tokio::spawn(async move {
                    if let Err(e) = relay(client, inner).await {
                        tracing::debug!("Foxglove connection ended: {e}");
                    }
                });
            }
            Err(e) => {
                // Out of file descriptors and the like: wait rather than spin.
                tracing::debug!("Foxglove accept: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

/// Relays one connection: its request head (renamed if need be), the
/// answer's head (renamed back), then everything else as it comes.
async fn relay(mut client: TcpStream, inner: SocketAddr) -> std::io::Result<()> {
    let (head, rest) = tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut client))
        .await
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::TimedOut, "no request head"))??;
    let (request, legacy) = rename_request(&head);
    let mut server = TcpStream::connect(inner).await?;
    server.set_nodelay(true)?;
    client.set_nodelay(true)?;
    server.write_all(request.as_bytes()).await?;
    server.write_all(&rest).await?;
    if legacy {
        let (answer, rest) = read_head(&mut server).await?;
        client.write_all(rename_answer(&answer).as_bytes()).await?;
        client.write_all(&rest).await?;
    }
    tokio::io::copy_bidirectional(&mut client, &mut server).await?;
    Ok(())
}

/// Reads up to the end of an HTTP head (`\r\n\r\n`): the head as text and
/// whatever bytes came after it.
async fn read_head<S: AsyncRead + Unpin>(stream: &mut S) -> std::io::Result<(String, Vec<u8>)> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 2048];
    loop {
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        let searched_from = buf.len().saturating_sub(3);
        buf.extend_from_slice(&chunk[..n]);
        if let Some(at) = buf[searched_from..]
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
        {
            let end = searched_from + at + 4;
            let rest = buf.split_off(end);
            let head = String::from_utf8(buf).map_err(|_| {
                std::io::Error::new(std::io::ErrorKind::InvalidData, "head not UTF-8")
            })?;
            return Ok((head, rest));
        }
        if buf.len() > MAX_HEAD {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "head too long",
            ));
        }
    }
}

/// The request head with the older subprotocol renamed to the SDK's, and
/// whether it was: only when the client offers the older name and none the
/// SDK accepts, so a client offering both is left to the SDK's choice.
pub fn rename_request(head: &str) -> (String, bool) {
    let offered: Vec<&str> = head
        .split("\r\n")
        .filter_map(|line| protocol_value(line))
        .flat_map(|value| value.split(','))
        .map(str::trim)
        .collect();
    let legacy =
        offered.contains(&LEGACY_SUBPROTOCOL) && !offered.iter().any(|o| SDK_NAMES.contains(o));
    if !legacy {
        return (head.to_string(), false);
    }
    let renamed = map_protocol_lines(head, |value| {
        value
            .split(',')
            .map(|o| {
                if o.trim() == LEGACY_SUBPROTOCOL {
                    SDK_SUBPROTOCOL
                } else {
                    o.trim()
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    });
    (renamed, true)
}

/// The answer head with the SDK's agreed subprotocol renamed back to the
/// older name the client asked for.
pub fn rename_answer(head: &str) -> String {
    map_protocol_lines(head, |value| {
        if value.trim() == SDK_SUBPROTOCOL {
            LEGACY_SUBPROTOCOL.to_string()
        } else {
            value.to_string()
        }
    })
}

/// The value of a `Sec-WebSocket-Protocol` header line, if `line` is one
/// (header names are case-insensitive).
fn protocol_value(line: &str) -> Option<&str> {
    let (name, value) = line.split_once(':')?;
    name.trim()
        .eq_ignore_ascii_case(PROTOCOL_HEADER)
        .then_some(value.trim())
}

/// `head` with every `Sec-WebSocket-Protocol` line's value passed through `f`.
fn map_protocol_lines(head: &str, f: impl Fn(&str) -> String) -> String {
    head.split("\r\n")
        .map(|line| match (protocol_value(line), line.split_once(':')) {
            (Some(value), Some((name, _))) => format!("{name}: {}", f(value)),
            _ => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\r\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(protocols: &str) -> String {
        format!(
            "GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\
             Sec-WebSocket-Protocol: {protocols}\r\n\r\n"
        )
    }

    #[test]
    fn the_older_name_is_renamed_for_the_sdk_and_back_for_the_client() {
        let (renamed, legacy) = rename_request(&request("foxglove.websocket.v1"));
        assert!(legacy);
        assert!(renamed.contains("Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n"));
        assert!(renamed.contains("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"));
        assert!(renamed.ends_with("\r\n\r\n"));
        let answer = "HTTP/1.1 101 Switching Protocols\r\nupgrade: websocket\r\n\
                      sec-websocket-protocol: foxglove.sdk.v1\r\n\r\n";
        let back = rename_answer(answer);
        assert!(back.contains("sec-websocket-protocol: foxglove.websocket.v1\r\n"));
        assert!(back.starts_with("HTTP/1.1 101 Switching Protocols\r\n"));
    }

    #[test]
    fn a_client_offering_an_sdk_name_is_left_to_the_sdk() {
        for offered in [
            "foxglove.sdk.v1",
            "foxglove.websocket.v1, foxglove.sdk.v1.1",
            "foxglove.sdk.v1,foxglove.websocket.v1",
        ] {
            let head = request(offered);
            assert_eq!(rename_request(&head), (head.clone(), false), "{offered}");
        }
    }

    #[test]
    fn other_names_are_not_renamed() {
        for offered in ["foxglove.websocket.v10", "chat", "foxglove.websocket"] {
            let head = request(offered);
            assert_eq!(rename_request(&head), (head.clone(), false), "{offered}");
        }
        let (renamed, legacy) = rename_request(&request("chat, foxglove.websocket.v1"));
        assert!(legacy);
        assert!(renamed.contains("Sec-WebSocket-Protocol: chat, foxglove.sdk.v1\r\n"));
    }

    #[tokio::test]
    async fn a_head_is_read_to_its_end_and_what_follows_is_kept() {
        let bytes = b"GET / HTTP/1.1\r\nA: b\r\n\r\n\x81\x00".to_vec();
        let (head, rest) = read_head(&mut bytes.as_slice()).await.expect("head");
        assert_eq!(head, "GET / HTTP/1.1\r\nA: b\r\n\r\n");
        assert_eq!(rest, vec![0x81, 0x00]);
        let endless = vec![b'a'; MAX_HEAD + 4096];
        assert!(read_head(&mut endless.as_slice()).await.is_err());
        assert!(
            read_head(&mut b"GET / HTTP/1.1\r\n".as_slice())
                .await
                .is_err()
        );
    }
}

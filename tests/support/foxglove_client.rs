//! A small client of Foxglove's published WebSocket protocol
//! (subprotocol `foxglove.sdk.v1`), written on `tungstenite` alone so that it
//! shares no code with the server it tests: it reads the advertised
//! channels, subscribes by topic and splits the binary message frames
//! (opcode 1: subscription id u32 LE, log time u64 LE, payload).

use std::collections::HashMap;
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// The subprotocol the client asks for.
pub const SUBPROTOCOL: &str = "foxglove.sdk.v1";

/// The same protocol's older name, which Lichtblick and Foxglove Studio
/// 1.x ask for.
pub const LEGACY_SUBPROTOCOL: &str = "foxglove.websocket.v1";

/// One advertised channel.
#[derive(Debug, Clone)]
pub struct ChannelInfo {
    /// Server's channel id.
    pub id: u64,
    /// Message encoding (`protobuf`, `json`).
    pub encoding: String,
    /// Schema name (`foxglove.SceneUpdate`, `ickon.RobotState`).
    pub schema_name: String,
}

/// A message received on a subscription.
#[derive(Debug, Clone)]
pub struct Received {
    /// Its topic.
    pub topic: String,
    /// The encoded message.
    pub payload: Vec<u8>,
}

/// A connected client.
pub struct FoxgloveClient {
    ws: WebSocket<TcpStream>,
    /// Advertised channels by topic.
    pub channels: HashMap<String, ChannelInfo>,
    /// Subscriptions: id -> topic.
    subscriptions: HashMap<u32, String>,
    next_subscription: u32,
}

impl FoxgloveClient {
    /// Connects to `addr`, asking for the protocol, and waits (up to
    /// `timeout`) for the server's info and its first advertisement.
    pub fn connect(addr: SocketAddr, timeout: Duration) -> Result<Self, String> {
        Self::connect_as(addr, timeout, SUBPROTOCOL)
    }

    /// [`Self::connect`], asking for `subprotocol` alone and insisting the
    /// server agrees to that very name.
    pub fn connect_as(
        addr: SocketAddr,
        timeout: Duration,
        subprotocol: &str,
    ) -> Result<Self, String> {
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(|e| e.to_string())?;
        stream
            .set_read_timeout(Some(Duration::from_millis(200)))
            .map_err(|e| e.to_string())?;
        let mut request = format!("ws://{addr}/")
            .into_client_request()
            .map_err(|e| e.to_string())?;
        request.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            subprotocol
                .parse()
                .map_err(|_| "subprotocol header value")?,
        );
        let (ws, response) = tungstenite::client(request, stream).map_err(|e| e.to_string())?;
        let agreed = response
            .headers()
            .get("Sec-WebSocket-Protocol")
            .and_then(|v| v.to_str().ok());
        if agreed != Some(subprotocol) {
            return Err(format!("server agreed to subprotocol {agreed:?}"));
        }
        let mut client = Self {
            ws,
            channels: HashMap::new(),
            subscriptions: HashMap::new(),
            next_subscription: 1,
        };
        let deadline = Instant::now() + timeout;
        while client.channels.is_empty() {
            if Instant::now() > deadline {
                return Err("no channel advertised".into());
            }
            client.read_one()?;
        }
        Ok(client)
    }

    /// Sends a raw frame (for garbage).
    pub fn send(&mut self, message: Message) -> Result<(), String> {
        self.ws.send(message).map_err(|e| e.to_string())
    }

    /// Subscribes to `topics` (each must be advertised).
    pub fn subscribe(&mut self, topics: &[&str]) -> Result<(), String> {
        let mut subs = Vec::new();
        for topic in topics {
            let channel = self
                .channels
                .get(*topic)
                .ok_or_else(|| format!("{topic} is not advertised"))?;
            let id = self.next_subscription;
            self.next_subscription += 1;
            self.subscriptions.insert(id, topic.to_string());
            subs.push(json!({"id": id, "channelId": channel.id}));
        }
        let text = json!({"op": "subscribe", "subscriptions": subs}).to_string();
        self.send(Message::text(text))
    }

    /// Reads one frame if one comes within the read timeout; a message on
    /// a subscription is returned, anything else is taken in.
    pub fn read_one(&mut self) -> Result<Option<Received>, String> {
        let message = match self.ws.read() {
            Ok(m) => m,
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) =>
            {
                return Ok(None);
            }
            Err(e) => return Err(e.to_string()),
        };
        match message {
            Message::Text(text) => {
                let v: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
                // Server info, status and the rest: not needed here.
                if v["op"].as_str() == Some("advertise") {
                    for c in v["channels"].as_array().into_iter().flatten() {
                        let (Some(id), Some(topic)) = (c["id"].as_u64(), c["topic"].as_str())
                        else {
                            return Err(format!("malformed channel {c}"));
                        };
                        self.channels.insert(
                            topic.to_string(),
                            ChannelInfo {
                                id,
                                encoding: c["encoding"].as_str().unwrap_or("").into(),
                                schema_name: c["schemaName"].as_str().unwrap_or("").into(),
                            },
                        );
                    }
                }
                Ok(None)
            }
            Message::Binary(bytes) => {
                if bytes.first() != Some(&1) || bytes.len() < 13 {
                    return Ok(None);
                }
                let sub = u32::from_le_bytes(bytes[1..5].try_into().expect("4 bytes"));
                let topic = self
                    .subscriptions
                    .get(&sub)
                    .ok_or_else(|| format!("message for unknown subscription {sub}"))?;
                Ok(Some(Received {
                    topic: topic.clone(),
                    payload: bytes[13..].to_vec(),
                }))
            }
            _ => Ok(None),
        }
    }

    /// Reads for `period`, returning every message received.
    pub fn read_for(&mut self, period: Duration) -> Result<Vec<Received>, String> {
        let end = Instant::now() + period;
        let mut out = Vec::new();
        while Instant::now() < end {
            if let Some(m) = self.read_one()? {
                out.push(m);
            }
        }
        Ok(out)
    }

    /// Closes the connection politely.
    pub fn close(mut self) {
        let _ = self.ws.close(None);
        let _ = self.ws.flush();
    }
}

//! `reload` queries, checked off the node's loop: decoding and validating a
//! site file of up to [`MAX_SITE_FILE_BYTES`] takes the TOML parser tens
//! of milliseconds and a few dozen times the file's size in memory, which
//! on the loop would skip cycle triggers. One file is checked at a time,
//! on a blocking thread; a `reload` that comes while one is being checked
//! is refused at once (the admin retries), so that the memory a reload can
//! take stays that of one file, however many are sent. Only a valid site
//! comes back to the loop, which swaps it in as before.

use ickon_proto::decode;
use ickon_proto::msg::admin::{AdminAck, ReloadRequest};
use ickon_proto::site::{MAX_SITE_FILE_BYTES, Site};
use tokio::sync::mpsc;
use zenoh::query::Query;

use crate::core::parse_reloaded_site;

/// A `reload` whose file has been checked.
pub(super) struct Checked {
    /// The query to answer.
    pub query: Query,
    /// The valid site with its text and file name, or why it was refused.
    pub result: Result<(Site, String, String), AdminAck>,
}

/// The reload checker: at most one file in flight.
pub(super) struct Reloads {
    in_flight: bool,
    done_tx: mpsc::Sender<Checked>,
    /// Where checked reloads arrive, for the node's loop.
    pub done: mpsc::Receiver<Checked>,
}

impl Reloads {
    /// A checker with nothing in flight.
    pub fn new() -> Self {
        let (done_tx, done) = mpsc::channel(1);
        Self {
            in_flight: false,
            done_tx,
            done,
        }
    }

    /// Whether a file is being checked: a `reload` now is refused with
    /// [`busy`].
    pub fn in_flight(&self) -> bool {
        self.in_flight
    }

    /// Starts checking the file of `query` (nothing may be in flight).
    pub fn start(&mut self, query: Query) {
        self.in_flight = true;
        let tx = self.done_tx.clone();
        tokio::task::spawn_blocking(move || {
            let result = check(&query);
            // The loop owns the receiver for as long as the node runs.
            let _ = tx.blocking_send(Checked { query, result });
        });
    }

    /// A checked reload arrived: the next may start.
    pub fn finished(&mut self) {
        self.in_flight = false;
    }
}

/// The answer to a `reload` while another file is being checked.
pub(super) fn busy() -> AdminAck {
    refused("another site file is being checked; send it again once that one is answered")
}

fn refused(message: &str) -> AdminAck {
    AdminAck {
        ok: false,
        messages: vec![message.to_string()],
    }
}

/// Decodes the request and parses and validates its site file.
fn check(query: &Query) -> Result<(Site, String, String), AdminAck> {
    let payload = query
        .payload()
        .ok_or_else(|| refused("reload needs a ReloadRequest payload"))?;
    // The encoded request holds the file and its name: refused before it
    // is copied when it cannot hold a site file of the allowed size.
    if payload.len() as u64 > MAX_SITE_FILE_BYTES + 4096 {
        return Err(refused(&format!(
            "a reload of {} bytes: site files are at most {MAX_SITE_FILE_BYTES} bytes",
            payload.len()
        )));
    }
    let request: ReloadRequest = decode(&payload.to_bytes())
        .map_err(|e| refused(&format!("reload needs a ReloadRequest payload: {e}")))?;
    let site = parse_reloaded_site(&request.site_toml, &request.file_name)?;
    Ok((site, request.site_toml, request.file_name))
}

//! `ickon sim --record FILE`: the launcher records its own run with the same
//! loop as `ickon record` ([`super::live`]), on its observer's session, from
//! before the first cell starts until the run's end. It also writes what a
//! replay needs to run the MSU cores exactly as the agents did: the noise
//! profile and, per robot, the estimator configuration, timing sigma and
//! drive geometry the agent was started with (MCAP metadata records
//! `ickon.sim` and `ickon.msu/<robot>`).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use ickon_proto::keys::Keys;
use tokio::sync::oneshot;

use super::live::{LiveError, record_site};
use super::{RecordReport, Recorder, base_metadata, cpu_seconds, create_output, write_failure};

/// Name of the metadata record of the simulation's settings.
pub const SIM_METADATA: &str = "ickon.sim";
/// Prefix of the metadata record of one robot's MSU agent settings.
pub const MSU_METADATA_PREFIX: &str = "ickon.msu/";

/// What the launcher started one MSU agent with.
#[derive(Debug, Clone)]
pub struct MsuStart {
    /// Robot id.
    pub robot: String,
    /// The estimator configuration as JSON (`--estimator-json`).
    pub estimator_json: String,
    /// One-sigma timing noise, microseconds.
    pub timing_sigma_us: f64,
    /// Wheel base, metres.
    pub wheel_base_m: f64,
    /// Metres per encoder tick.
    pub m_per_tick: f64,
}

/// What the recording task hands back: the writer and why it stopped.
type Finished = (Recorder<BufWriter<File>>, Result<(), LiveError>);

/// A recording running beside `ickon sim`.
pub struct SimRecording {
    path: PathBuf,
    stop: oneshot::Sender<()>,
    task: tokio::task::JoinHandle<Finished>,
    started: Instant,
    cpu0: f64,
}

/// The metadata records of a simulated run.
pub fn sim_metadata(
    site: &str,
    settings: &[(&str, String)],
    msus: &[MsuStart],
) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut m = base_metadata(site);
    m.insert(
        SIM_METADATA.to_string(),
        settings
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect(),
    );
    for s in msus {
        m.insert(
            format!("{MSU_METADATA_PREFIX}{}", s.robot),
            BTreeMap::from([
                ("estimator_json".to_string(), s.estimator_json.clone()),
                ("timing_sigma_us".to_string(), s.timing_sigma_us.to_string()),
                ("wheel_base_m".to_string(), s.wheel_base_m.to_string()),
                ("m_per_tick".to_string(), s.m_per_tick.to_string()),
            ]),
        );
    }
    m
}

/// Opens the recorder's own session: a peer listening on `listen` (which
/// the world, the cells and the MSU agents are told to connect to, so that
/// their first messages already reach it: in a peer mesh data goes only over
/// direct links, and a link made later by gossip would miss them) and
/// connected to the central unit.
pub async fn open_session(
    central: &str,
    listen: &str,
    credential: Option<&std::path::Path>,
) -> Result<zenoh::Session, String> {
    let mut config = match credential {
        Some(f) => zenoh::Config::from_file(f).map_err(|e| format!("{}: {e}", f.display()))?,
        None => zenoh::Config::default(),
    };
    for (k, v) in [
        ("mode", "\"peer\"".to_string()),
        ("listen/endpoints", format!("[\"{listen}\"]")),
        ("connect/endpoints", format!("[\"{central}\"]")),
        ("scouting/multicast/enabled", "false".to_string()),
    ] {
        config
            .insert_json5(k, &v)
            .map_err(|e| format!("zenoh config {k}: {e}"))?;
    }
    zenoh::open(config)
        .await
        .map_err(|e| format!("cannot open the recorder's Zenoh session: {e}"))
}

impl SimRecording {
    /// Creates `path` and starts recording everything of the site of `keys`.
    pub fn start(
        session: &zenoh::Session,
        keys: &Keys,
        path: &Path,
        metadata: &BTreeMap<String, BTreeMap<String, String>>,
        with_view: bool,
    ) -> Result<Self, String> {
        let out = create_output(path)?;
        let mut recorder =
            Recorder::new(out, keys.clone(), metadata).map_err(|e| write_failure(path, &e))?;
        let (stop, stopped) = oneshot::channel::<()>();
        let session = session.clone();
        let keys = keys.clone();
        let task = tokio::spawn(async move {
            let pattern = keys.everything();
            let r = record_site(&session, &keys, &pattern, &mut recorder, with_view, async {
                let _ = stopped.await;
            })
            .await;
            (recorder, r)
        });
        Ok(Self {
            path: path.to_path_buf(),
            stop,
            task,
            started: Instant::now(),
            cpu0: cpu_seconds(),
        })
    }

    /// Stops the recording and finishes the file.
    pub async fn finish(self) -> Result<RecordReport, String> {
        let _ = self.stop.send(());
        let (recorder, outcome) = self
            .task
            .await
            .map_err(|e| format!("the recorder task failed: {e}"))?;
        if let Err(e) = outcome {
            return Err(match e {
                LiveError::Record(e) => write_failure(&self.path, &e),
                other => format!("the recording {} stopped: {other}", self.path.display()),
            });
        }
        let (stats, out) = recorder
            .finish()
            .map_err(|e| write_failure(&self.path, &e))?;
        let file = out
            .into_inner()
            .map_err(|e| write_failure(&self.path, &super::RecordError::Write(e.into_error())))?;
        file.sync_all()
            .map_err(|e| write_failure(&self.path, &super::RecordError::Write(e)))?;
        Ok(RecordReport::new(
            &self.path,
            stats,
            cpu_seconds() - self.cpu0,
            self.started.elapsed().as_secs_f64(),
        ))
    }
}

//! Joining a site: what every node does before its own work. It shows
//! itself with a liveliness token, asks the central unit for the site
//! (retrying until it answers), parses it with the same code as every other
//! process, and subscribes to the keys it listens to. The order of these
//! steps is the node's choice: a node that must hear the schedule before
//! the central unit schedules it subscribes before it shows its token.

use std::future::Future;
use std::time::Duration;

use ickon_proto::keys::Keys;
use ickon_proto::msg::control::{Schedule, SiteInfo};
use ickon_proto::site::Site;
use zenoh::Session;
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

use crate::{NodeError, fetch, query_once, zerr};

/// How long a node waits between asking the central unit again at start-up.
pub const FETCH_RETRY: Duration = Duration::from_millis(500);

/// The name a site fetched from the central unit is parsed under (the
/// origin its parse errors name).
const FETCHED_ORIGIN: &str = "<site from the central unit>";

/// A subscriber whose samples are read from a queue.
pub type QueuedSubscriber = Subscriber<FifoChannelHandler<Sample>>;

/// The site as the central unit serves it: its message and the parsed site.
#[derive(Debug, Clone)]
pub struct JoinedSite {
    /// What the central unit sent (name, version, the site file).
    pub info: SiteInfo,
    /// The site file, parsed and checked.
    pub site: Site,
}

/// One node's way into a site: the session and the site's keys.
#[derive(Clone, Copy)]
pub struct SiteJoin<'s> {
    session: &'s Session,
    keys: &'s Keys,
}

impl<'s> SiteJoin<'s> {
    /// Joins the site whose keys are `keys` through `session`.
    pub fn new(session: &'s Session, keys: &'s Keys) -> Self {
        Self { session, keys }
    }

    /// The site's keys.
    pub fn keys(&self) -> &'s Keys {
        self.keys
    }

    /// The session the node joined through.
    pub fn session(&self) -> &'s Session {
        self.session
    }

    /// Declares the liveliness token `key` (e.g. [`Keys::alive_robot`]): the
    /// node is seen as up while the token is held.
    pub async fn announce(&self, key: String) -> Result<LivelinessToken, NodeError> {
        self.session
            .liveliness()
            .declare_token(key)
            .await
            .map_err(zerr)
    }

    /// Asks the central unit for the site until it answers, and parses it;
    /// `None` when `shutdown` completes first.
    pub async fn site(
        &self,
        shutdown: &mut (impl Future<Output = ()> + Unpin),
    ) -> Result<Option<JoinedSite>, NodeError> {
        let key = self.keys.central_site();
        let Some(info) = fetch::<SiteInfo>(self.session, &key, None, FETCH_RETRY, shutdown).await?
        else {
            return Ok(None);
        };
        let site = parse_site(&info)?;
        Ok(Some(JoinedSite { info, site }))
    }

    /// Asks the central unit for the schedule in force until it answers;
    /// `None` when `shutdown` completes first.
    pub async fn schedule(
        &self,
        shutdown: &mut (impl Future<Output = ()> + Unpin),
    ) -> Result<Option<Schedule>, NodeError> {
        let key = self.keys.central_schedule();
        fetch::<Schedule>(self.session, &key, None, FETCH_RETRY, shutdown).await
    }

    /// Asks the central unit once for the schedule in force: `None` when it
    /// did not answer within `timeout`.
    pub async fn schedule_once(&self, timeout: Duration) -> Result<Option<Schedule>, NodeError> {
        query_once::<Schedule>(self.session, &self.keys.central_schedule(), None, timeout).await
    }

    /// Subscribes to `key`, its samples queued until read.
    pub async fn subscribe(&self, key: String) -> Result<QueuedSubscriber, NodeError> {
        self.session.declare_subscriber(key).await.map_err(zerr)
    }

    /// Subscribes to `key`, each sample handed to `callback` as it arrives.
    pub async fn subscribe_with(
        &self,
        key: String,
        callback: impl Fn(Sample) + Send + Sync + 'static,
    ) -> Result<Subscriber<()>, NodeError> {
        self.session
            .declare_subscriber(key)
            .callback(callback)
            .await
            .map_err(zerr)
    }

    /// Watches the liveliness tokens matching `key`, those present now
    /// included (each a `Put`, and a `Delete` when it goes).
    pub async fn watch_tokens(&self, key: String) -> Result<QueuedSubscriber, NodeError> {
        self.session
            .liveliness()
            .declare_subscriber(key)
            .history(true)
            .await
            .map_err(zerr)
    }
}

/// The site in `info`, parsed and checked as every node does.
pub fn parse_site(info: &SiteInfo) -> Result<Site, NodeError> {
    Ok(Site::from_toml(&info.site_toml, FETCHED_ORIGIN)?)
}

#[cfg(test)]
#[path = "site_join_tests.rs"]
mod tests;

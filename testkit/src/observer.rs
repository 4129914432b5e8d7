//! The test's own Zenoh session on the loopback mesh.

use zenoh::{Session, Wait};

/// A Zenoh peer of the test: listens on a free loopback port (found by
/// binding port 0 and reading the port back: Zenoh 1.10 reports its own
/// bound locators only behind its unstable feature), multicast scouting off,
/// connected to the given endpoints. Uses the blocking API, so plain
/// `#[test]` functions can use it (no async runtime needed).
pub struct Observer {
    session: Session,
    listen: String,
}

impl Observer {
    /// Opens the session, connecting to `connect`.
    pub fn open(connect: &[String]) -> zenoh::Result<Self> {
        let listen = crate::loopback_endpoint()?;
        let mut config = zenoh::Config::default();
        config.insert_json5("mode", "\"peer\"")?;
        config.insert_json5("listen/endpoints", &format!("[{listen:?}]"))?;
        config.insert_json5("scouting/multicast/enabled", "false")?;
        let endpoints: Vec<String> = connect.iter().map(|e| format!("{e:?}")).collect();
        config.insert_json5("connect/endpoints", &format!("[{}]", endpoints.join(",")))?;
        Ok(Self {
            session: zenoh::open(config).wait()?,
            listen,
        })
    }

    /// The session.
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The endpoint the session listens on, for other peers to connect to.
    pub fn endpoint(&self) -> &str {
        &self.listen
    }
}

impl Drop for Observer {
    fn drop(&mut self) {
        let _ = self.session.close().wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn two_observers_meet_on_the_port_read_back() {
        let a = Observer::open(&[]).unwrap();
        assert!(
            a.endpoint().starts_with("tcp/127.0.0.1:"),
            "{}",
            a.endpoint()
        );
        assert!(!a.endpoint().ends_with(":0"));
        let b = Observer::open(&[a.endpoint().to_string()]).unwrap();
        let sub = a.session().declare_subscriber("kit/test").wait().unwrap();
        let publisher = b.session().declare_publisher("kit/test").wait().unwrap();
        // Puts made before the route exists are lost: put until one arrives.
        let got = crate::poll_until(Duration::from_secs(10), "a sample", || {
            publisher.put("x").wait().ok()?;
            sub.try_recv().ok().flatten()
        })
        .unwrap();
        assert_eq!(got.payload().to_bytes().as_ref(), b"x");
    }
}

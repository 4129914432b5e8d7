//! Where a device is: `serial:PATH[@BAUD]` or `tcp:HOST:PORT`.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

/// The serial speed when an address names none.
pub const DEFAULT_BAUD: u32 = 115_200;

/// A device's address, as given on a command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkAddress {
    /// A serial port (a USB adapter, a UART, a pseudo-terminal).
    Serial {
        /// Its device path, e.g. `/dev/ttyUSB0`.
        path: PathBuf,
        /// Bits per second (8N1, no flow control).
        baud: u32,
    },
    /// A TCP server: the board itself or a serial-to-network bridge.
    Tcp {
        /// Host name or address.
        host: String,
        /// Port.
        port: u16,
    },
}

/// Why a text is not a [`LinkAddress`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AddressError {
    /// Neither prefix.
    #[error("{0:?}: a device address is serial:PATH[@BAUD] or tcp:HOST:PORT")]
    Scheme(String),
    /// An empty path.
    #[error("{0:?}: the serial path is empty (serial:PATH[@BAUD])")]
    EmptyPath(String),
    /// A baud rate that is not a positive number.
    #[error("{0:?}: the baud rate must be a positive whole number (serial:PATH[@BAUD])")]
    Baud(String),
    /// No host or no valid port.
    #[error("{0:?}: expected tcp:HOST:PORT with a port of 1-65535")]
    HostPort(String),
}

impl FromStr for LinkAddress {
    type Err = AddressError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Some(rest) = s.strip_prefix("serial:") {
            let (path, baud) = match rest.rsplit_once('@') {
                Some((path, baud)) => {
                    let baud: u32 = baud.parse().map_err(|_| AddressError::Baud(s.into()))?;
                    if baud == 0 {
                        return Err(AddressError::Baud(s.into()));
                    }
                    (path, baud)
                }
                None => (rest, DEFAULT_BAUD),
            };
            if path.is_empty() {
                return Err(AddressError::EmptyPath(s.into()));
            }
            return Ok(LinkAddress::Serial {
                path: PathBuf::from(path),
                baud,
            });
        }
        if let Some(rest) = s.strip_prefix("tcp:") {
            let (host, port) = rest
                .rsplit_once(':')
                .ok_or_else(|| AddressError::HostPort(s.into()))?;
            let port: u16 = port
                .parse()
                .ok()
                .filter(|&p| p > 0)
                .ok_or_else(|| AddressError::HostPort(s.into()))?;
            let host = host.trim_start_matches('[').trim_end_matches(']');
            if host.is_empty() {
                return Err(AddressError::HostPort(s.into()));
            }
            return Ok(LinkAddress::Tcp {
                host: host.to_string(),
                port,
            });
        }
        Err(AddressError::Scheme(s.into()))
    }
}

impl fmt::Display for LinkAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkAddress::Serial { path, baud } => write!(f, "serial:{}@{baud}", path.display()),
            LinkAddress::Tcp { host, port } if host.contains(':') => {
                write!(f, "tcp:[{host}]:{port}")
            }
            LinkAddress::Tcp { host, port } => write!(f, "tcp:{host}:{port}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_both_kinds_with_and_without_a_baud_rate() {
        assert_eq!(
            "serial:/dev/ttyUSB0".parse(),
            Ok(LinkAddress::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: DEFAULT_BAUD
            })
        );
        assert_eq!(
            "serial:/dev/ttyACM1@921600".parse(),
            Ok(LinkAddress::Serial {
                path: "/dev/ttyACM1".into(),
                baud: 921_600
            })
        );
        assert_eq!(
            "tcp:10.0.0.7:4000".parse(),
            Ok(LinkAddress::Tcp {
                host: "10.0.0.7".into(),
                port: 4000
            })
        );
        let v6: LinkAddress = "tcp:[::1]:4000".parse().unwrap();
        assert_eq!(v6.to_string(), "tcp:[::1]:4000");
    }

    #[test]
    fn refuses_what_is_not_an_address_with_the_form_it_expects() {
        for bad in [
            "",
            "/dev/ttyUSB0",
            "serial:",
            "serial:/dev/x@0",
            "serial:/dev/x@fast",
            "tcp:host",
            "tcp::4000",
            "tcp:host:0",
            "tcp:host:70000",
            "udp:host:1",
        ] {
            let e = bad.parse::<LinkAddress>().unwrap_err();
            assert!(
                e.to_string().contains("serial:") || e.to_string().contains("tcp:"),
                "{bad}: {e}"
            );
        }
    }
}

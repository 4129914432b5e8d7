//! Free loopback ports.

/// A loopback TCP port that was free a moment ago: the kernel picks it when
/// binding port 0, the port is read back and the socket released. Another
/// process could take it in between; a node that cannot bind it fails at
/// once, which the tests see as an early exit.
pub fn free_tcp_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// `tcp/127.0.0.1:<port>` on a free port.
pub fn loopback_endpoint() -> std::io::Result<String> {
    Ok(format!("tcp/127.0.0.1:{}", free_tcp_port()?))
}

/// Whether something accepts TCP connections on `127.0.0.1:port`.
pub fn accepts(port: u16) -> bool {
    std::net::TcpStream::connect_timeout(
        &std::net::SocketAddr::from(([127, 0, 0, 1], port)),
        std::time::Duration::from_millis(200),
    )
    .is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_free_port_can_be_bound_and_then_accepts() {
        let port = free_tcp_port().unwrap();
        assert!(port > 0);
        let listener = std::net::TcpListener::bind(("127.0.0.1", port)).unwrap();
        assert!(accepts(port));
        drop(listener);
        assert!(loopback_endpoint().unwrap().starts_with("tcp/127.0.0.1:"));
    }
}

//! Loopback ports for the nodes of `ickon sim`, chosen before the nodes
//! start.

/// A free loopback TCP port for the central unit to listen on (bound and
/// released; the node binds it right after). It is taken below the kernel's
/// ephemeral range: the other nodes connect to it before it listens, and a
/// connect to a free port inside that range can be given the same port as
/// its own source and connect to itself (seen once: the central then found
/// its port taken). `taken`: ports already handed out but not bound yet.
pub(crate) fn free_port(taken: &[u16]) -> std::io::Result<u16> {
    let ephemeral_low = std::fs::read_to_string("/proc/sys/net/ipv4/ip_local_port_range")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u16>().ok())
        .unwrap_or(32_768);
    const LOWEST: u16 = 10_000;
    if ephemeral_low > LOWEST + 100 {
        let span = u32::from(ephemeral_low - LOWEST);
        let start = std::process::id() % span;
        for k in 0..span.min(2_000) {
            let port = LOWEST + u16::try_from((start + k * 7) % span).unwrap_or(0);
            if !taken.contains(&port) && std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
                return Ok(port);
            }
        }
    }
    loop {
        let port = std::net::TcpListener::bind("127.0.0.1:0")?
            .local_addr()?
            .port();
        if !taken.contains(&port) {
            return Ok(port);
        }
    }
}

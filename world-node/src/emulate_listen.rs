//! The emulators' TCP listener (`--listen`): it announces the address a
//! host connects to, for whoever started the emulator to read. Shared by
//! the board emulator ([`crate::emulate`]) and the hedgehog's
//! ([`crate::emulate_hedgehog`]).

use std::io::Write;
use std::net::TcpListener;

use ickon_runtime::CommandError;

/// Listens on `addr` (`--listen`) and prints the address a host connects
/// to (`tcp:HOST:PORT`) on stdout at once, for whoever started the
/// emulator to read.
pub(crate) fn listen_announced(addr: &str) -> Result<TcpListener, CommandError> {
    let listener = TcpListener::bind(addr)
        .map_err(|e| CommandError::bad_input(format!("--listen {addr}: {e}")))?;
    let local = listener
        .local_addr()
        .map_err(|e| CommandError::failure(e.to_string()))?;
    println!("tcp:{local}");
    let _ = std::io::stdout().flush();
    Ok(listener)
}

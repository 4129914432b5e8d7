//! Reading a configuration-sized text file (a site file, an MSU
//! configuration) with a bound: a wrong path to a log, a device or a pipe
//! must not be read into memory whole.

use std::io::Read;
use std::path::Path;

/// Reads `path` as UTF-8 text of at most `max_bytes` bytes. `Err` says why
/// in words (the caller names the file): it cannot be read, it is larger
/// than `max_bytes` (found without reading more than one byte past the
/// bound, so a pipe or a device that never ends is refused too), or it is
/// not UTF-8.
pub fn read_bounded(path: &Path, max_bytes: u64) -> Result<String, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > max_bytes {
        return Err(format!(
            "larger than {max_bytes} bytes, more than a file of this kind can be"
        ));
    }
    String::from_utf8(bytes).map_err(|e| format!("not UTF-8 text: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_the_bound_is_refused_and_one_at_it_is_read() {
        let dir = std::env::temp_dir().join(format!("ickon-text-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.toml");
        std::fs::write(&path, "a".repeat(100)).unwrap();
        assert_eq!(read_bounded(&path, 100).unwrap().len(), 100);
        let e = read_bounded(&path, 99).unwrap_err();
        assert!(e.contains("larger than 99 bytes"), "{e}");
        std::fs::write(&path, [0xff, 0xfe]).unwrap();
        assert!(read_bounded(&path, 100).unwrap_err().contains("UTF-8"));
        assert!(read_bounded(&dir.join("missing"), 100).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_device_that_never_ends_is_refused() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 16).unwrap_err();
        assert!(e.contains("larger than"), "{e}");
    }
}

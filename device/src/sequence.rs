//! Arrival groups as one sequence: a board numbers its groups of
//! arrivals with a 16-bit counter; hosts and observers number a robot's
//! cycles with a 64-bit one.

/// Unwraps a board's 16-bit arrival group counter into the sequence
/// number of the arrivals it carries, so that the world (which frames the
/// groups) and the MSU (which reads them) number a robot's cycles alike.
#[derive(Debug, Default, Clone, Copy)]
pub struct GroupSequence {
    last: Option<(u16, u64)>,
}

impl GroupSequence {
    /// The sequence number of group `group`.
    pub fn next(&mut self, group: u16) -> u64 {
        let seq = match self.last {
            Some((g, s)) => s + u64::from(group.wrapping_sub(g).max(1)),
            None => u64::from(group),
        };
        self.last = Some((group, seq));
        seq
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group_numbers_unwrap_into_one_sequence() {
        let mut s = GroupSequence::default();
        assert_eq!(s.next(65_534), 65_534);
        assert_eq!(s.next(65_535), 65_535);
        assert_eq!(s.next(0), 65_536);
        // A lost group leaves a gap, as it does on the other side.
        assert_eq!(s.next(2), 65_538);
        // A repeated group number still moves on.
        assert_eq!(s.next(2), 65_539);
    }
}

//! Transmitters failing in the world: `dead:tx/ID@T` (silent from `T`),
//! `weak:tx/ID@T=FACTOR` (each burst heard with that probability of what
//! it would have been: a transducer losing its output, a board's supply
//! sagging) and `moved:tx/ID@T=DX,DY,DZ` (knocked by a forklift: it hangs
//! that far, metres, from where the site file says). `T` takes `s` or
//! `ms`. The same items are taken by `ickon eval --faults` and
//! `ickon sim --faults`, beside the faults of processes.

use ickon_proto::site::Site;

/// What goes wrong with a transmitter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TransmitterFaultKind {
    /// It stops firing.
    Dead,
    /// Each burst is heard with this probability of what it would have been.
    Weak(f64),
    /// It hangs this far from its surveyed position, metres.
    Moved([f64; 3]),
}

/// One transmitter fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransmitterFault {
    /// The transmitter.
    pub tx_id: u32,
    /// From when, seconds from the start of the run.
    pub at_s: f64,
    /// What happens.
    pub kind: TransmitterFaultKind,
}

/// Why a fault item could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--faults: {item:?}: {why}")]
pub struct TransmitterFaultError {
    /// The item the problem is in.
    pub item: String,
    /// What is wrong with it.
    pub why: String,
}

/// The longest time a fault may name, seconds (a day): `@100000s` is a typo.
const LONGEST_S: f64 = 86_400.0;

/// The farthest a moved transmitter may be, metres: further is a
/// transmitter in another place, which the site file must say.
const FARTHEST_MOVE_M: f64 = 5.0;

impl TransmitterFault {
    /// Whether `item` is a transmitter fault (its action is one of
    /// `dead`, `weak`, `moved`).
    pub fn is_one(item: &str) -> bool {
        matches!(
            item.trim().split(':').next(),
            Some("dead" | "weak" | "moved")
        )
    }

    /// Reads one item, checking its transmitter against `site`.
    pub fn parse(item: &str, site: &Site) -> Result<Self, TransmitterFaultError> {
        let item = item.trim();
        let bad = |why: String| TransmitterFaultError {
            item: item.to_string(),
            why,
        };
        let (action, rest) = item
            .split_once(':')
            .ok_or_else(|| bad("expected ACTION:tx/ID@TIME".into()))?;
        let (target, rest) = rest
            .split_once('@')
            .ok_or_else(|| bad("expected @TIME after the transmitter".into()))?;
        let id_text = target
            .strip_prefix("tx/")
            .ok_or_else(|| bad(format!("{target:?} is not a transmitter (write tx/ID)")))?;
        let tx_id: u32 = id_text
            .parse()
            .map_err(|_| bad(format!("{id_text:?} is not a transmitter id")))?;
        if site.transmitter(tx_id).is_none() {
            let known: Vec<String> = site.transmitters.iter().map(|t| t.id.to_string()).collect();
            return Err(bad(format!(
                "the site has no transmitter {tx_id} (it has {})",
                known.join(", ")
            )));
        }
        let (time, value) = match rest.split_once('=') {
            Some((t, v)) => (t, Some(v)),
            None => (rest, None),
        };
        let at_s = parse_time_s(time).map_err(bad)?;
        let kind = match (action, value) {
            ("dead", None) => TransmitterFaultKind::Dead,
            ("dead", Some(_)) => return Err(bad("dead takes no value".into())),
            ("weak", Some(v)) => {
                let f: f64 = v
                    .parse()
                    .map_err(|_| bad(format!("{v:?} is not a number")))?;
                if !(f > 0.0 && f < 1.0) {
                    return Err(bad(format!(
                        "a weak transmitter is heard a fraction above 0 and below 1 of the time, not {v}"
                    )));
                }
                TransmitterFaultKind::Weak(f)
            }
            ("moved", Some(v)) => {
                let d: Vec<f64> = v
                    .split(',')
                    .map(|p| p.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad(format!("{v:?} is not DX,DY,DZ in metres")))?;
                let [dx, dy, dz] = d[..] else {
                    return Err(bad(format!("{v:?} is not DX,DY,DZ in metres")));
                };
                if !d.iter().all(|x| x.is_finite()) {
                    return Err(bad(format!("{v:?} is not DX,DY,DZ in metres")));
                }
                let norm = (dx * dx + dy * dy + dz * dz).sqrt();
                if norm > FARTHEST_MOVE_M {
                    return Err(bad(format!(
                        "a move of {norm} m is beyond {FARTHEST_MOVE_M} m: put the transmitter's new place in the site file"
                    )));
                }
                TransmitterFaultKind::Moved([dx, dy, dz])
            }
            ("weak" | "moved", None) => {
                return Err(bad(format!("{action} needs =VALUE after the time")));
            }
            (other, _) => return Err(bad(format!("unknown action {other:?}"))),
        };
        Ok(Self { tx_id, at_s, kind })
    }

    /// Reads every transmitter fault of a comma-separated plan, ignoring
    /// the other items (the process faults of `ickon sim`).
    pub fn parse_plan(plan: &str, site: &Site) -> Result<Vec<Self>, TransmitterFaultError> {
        split_plan(plan)
            .iter()
            .filter(|item| Self::is_one(item))
            .map(|item| Self::parse(item, site))
            .collect()
    }

    /// The item as `--faults` takes it.
    pub fn to_item(&self) -> String {
        let at = format!("{}ms", (self.at_s * 1e3).round() as i64);
        match self.kind {
            TransmitterFaultKind::Dead => format!("dead:tx/{}@{at}", self.tx_id),
            TransmitterFaultKind::Weak(f) => format!("weak:tx/{}@{at}={f}", self.tx_id),
            TransmitterFaultKind::Moved([x, y, z]) => {
                format!("moved:tx/{}@{at}={x},{y},{z}", self.tx_id)
            }
        }
    }
}

/// The items of a comma-separated fault plan: every item starts with
/// `ACTION:`, so a piece without a colon after a `moved:` item's value is
/// the rest of it (the `DY,DZ` of `moved:tx/ID@T=DX,DY,DZ`); any other
/// piece is an item of its own. Empty pieces are dropped.
pub fn split_plan(plan: &str) -> Vec<String> {
    let mut items: Vec<String> = Vec::new();
    for piece in plan.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        match items.last_mut() {
            Some(last)
                if !piece.contains(':')
                    && last.starts_with("moved:")
                    && last.contains('=')
                    && last.matches(',').count() < 2 =>
            {
                last.push(',');
                last.push_str(piece);
            }
            _ => items.push(piece.to_string()),
        }
    }
    items
}

fn parse_time_s(text: &str) -> Result<f64, String> {
    let (number, scale) = if let Some(n) = text.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = text.strip_suffix('s') {
        (n, 1.0)
    } else {
        return Err(format!("{text:?} needs a unit: s or ms"));
    };
    let v: f64 = number
        .parse()
        .map_err(|_| format!("{text:?} is not a time"))?;
    let s = v * scale;
    if !(s.is_finite() && (0.0..=LONGEST_S).contains(&s)) {
        return Err(format!("{text:?} is not within 0 s to a day"));
    }
    Ok(s)
}

/// The faults of a run, applied to what the world hears.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TransmitterFaults {
    faults: Vec<TransmitterFault>,
}

impl TransmitterFaults {
    /// The world's faults.
    pub fn new(faults: Vec<TransmitterFault>) -> Self {
        Self { faults }
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty()
    }

    /// Whether `tx_id` is silent at `t_s`.
    pub fn dead(&self, tx_id: u32, t_s: f64) -> bool {
        self.active(tx_id, t_s)
            .any(|f| f.kind == TransmitterFaultKind::Dead)
    }

    /// The probability that a burst of `tx_id` at `t_s` is heard, of what it
    /// would have been (1 when healthy).
    pub fn strength(&self, tx_id: u32, t_s: f64) -> f64 {
        self.active(tx_id, t_s)
            .filter_map(|f| match f.kind {
                TransmitterFaultKind::Weak(k) => Some(k),
                _ => None,
            })
            .product()
    }

    /// How far `tx_id` hangs from its place at `t_s`, metres.
    pub fn displacement(&self, tx_id: u32, t_s: f64) -> [f64; 3] {
        self.active(tx_id, t_s)
            .filter_map(|f| match f.kind {
                TransmitterFaultKind::Moved(d) => Some(d),
                _ => None,
            })
            .fold([0.0; 3], |a, d| [a[0] + d[0], a[1] + d[1], a[2] + d[2]])
    }

    fn active(&self, tx_id: u32, t_s: f64) -> impl Iterator<Item = &TransmitterFault> {
        self.faults
            .iter()
            .filter(move |f| f.tx_id == tx_id && t_s >= f.at_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_reads_and_writes_back() {
        let site = Site::default_site();
        for item in [
            "dead:tx/22@10s",
            "weak:tx/22@30s=0.25",
            "moved:tx/41@2500ms=0.3,0,-0.05",
        ] {
            let f = TransmitterFault::parse(item, &site).unwrap();
            assert_eq!(
                TransmitterFault::parse(&f.to_item(), &site).unwrap(),
                f,
                "{item}"
            );
        }
        let plan = "kill:cell/c1@5s, dead:tx/22@10s,moved:tx/24@2s=0.3, 0,0,weak:tx/23@1s=0.5";
        assert_eq!(split_plan(plan).len(), 4, "{:?}", split_plan(plan));
        assert_eq!(split_plan("kill:central@1s,,oops").len(), 2);
        assert_eq!(split_plan("moved:tx/1@1s=1,2,3,4").len(), 2);
        let faults = TransmitterFault::parse_plan(plan, &site).unwrap();
        assert_eq!(faults.len(), 3);
        assert_eq!(faults[1].kind, TransmitterFaultKind::Moved([0.3, 0.0, 0.0]));
        let faults = vec![faults[0], faults[2]];
        let w = TransmitterFaults::new(faults);
        assert!(!w.dead(22, 9.9) && w.dead(22, 10.0));
        assert_eq!(w.strength(23, 0.5), 1.0);
        assert_eq!(w.strength(23, 1.5), 0.5);
        assert_eq!(w.displacement(22, 100.0), [0.0; 3]);
    }

    #[test]
    fn absurd_items_are_refused_with_the_reason() {
        let site = Site::default_site();
        let cases = [
            ("dead:tx/999@1s", "no transmitter 999"),
            ("dead:cell/c1@1s", "not a transmitter"),
            ("dead:tx/22", "@TIME"),
            ("dead:tx/22@1", "needs a unit"),
            ("dead:tx/22@-1s", "within 0 s"),
            ("dead:tx/22@100000s", "within 0 s"),
            ("dead:tx/22@1s=3", "takes no value"),
            ("weak:tx/22@1s", "needs =VALUE"),
            ("weak:tx/22@1s=1.5", "above 0 and below 1"),
            ("weak:tx/22@1s=nan", "above 0 and below 1"),
            ("moved:tx/22@1s=1,2", "DX,DY,DZ"),
            ("moved:tx/22@1s=10,0,0", "beyond"),
            ("moved:tx/22@1s=inf,0,0", "DX,DY,DZ"),
            ("moved:tx/22@1s=0.3,NaN,0", "DX,DY,DZ"),
            ("weak:tx/abc@1s=0.5", "not a transmitter id"),
        ];
        for (item, why) in cases {
            let err = TransmitterFault::parse(item, &site)
                .unwrap_err()
                .to_string();
            assert!(err.contains(why), "{item}: {err}");
        }
    }
}

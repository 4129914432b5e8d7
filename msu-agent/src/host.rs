//! The MSU's fusion host: one or several estimators fed the same inputs.
//! The live agent hosts one; `ickon eval` hosts every estimator it compares,
//! so each cycle is solved once and every estimator sees the same fix.

use ickon_fusion::estimator::{Estimator, EstimatorError, Input, PoseEstimate};

/// Estimators fed alike; the first is the primary (its pose is published).
pub struct FusionHost {
    estimators: Vec<Box<dyn Estimator>>,
    refused: Vec<u64>,
}

impl FusionHost {
    /// A host of `estimators`; the first is the primary. At least one is needed.
    pub fn new(estimators: Vec<Box<dyn Estimator>>) -> Self {
        let refused = vec![0; estimators.len()];
        Self {
            estimators,
            refused,
        }
    }

    /// Feeds `input` to every estimator; the primary's refusal is returned,
    /// every refusal is counted per estimator. A refused input leaves that
    /// estimator as it was.
    pub fn feed(&mut self, input: &Input) -> Result<(), EstimatorError> {
        let mut primary = Ok(());
        for (i, e) in self.estimators.iter_mut().enumerate() {
            if let Err(err) = e.handle(input) {
                self.refused[i] += 1;
                if i == 0 {
                    primary = Err(err);
                }
            }
        }
        primary
    }

    /// Number of estimators.
    pub fn len(&self) -> usize {
        self.estimators.len()
    }

    /// Whether no estimator is hosted.
    pub fn is_empty(&self) -> bool {
        self.estimators.is_empty()
    }

    /// Estimator `i`'s name.
    pub fn name(&self, i: usize) -> Option<&'static str> {
        self.estimators.get(i).map(|e| e.name())
    }

    /// Estimator `i`'s pose, once it is initialised.
    pub fn pose(&self, i: usize) -> Option<PoseEstimate> {
        self.estimators.get(i)?.pose()
    }

    /// Inputs estimator `i` refused so far.
    pub fn refused(&self, i: usize) -> u64 {
        self.refused.get(i).copied().unwrap_or(0)
    }
}

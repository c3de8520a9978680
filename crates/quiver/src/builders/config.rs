//! [`BuildConfig`]: the settings every builder shares, and how a bad one is named.

use super::CostModel;

/// Settings shared by the builders.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildConfig {
    /// Bins per axis in the binned builder, 2 to 1024.
    pub bins: usize,
    /// Largest leaf a build may make; nodes above it are always split.
    pub max_leaf_size: usize,
    /// SAH cost of visiting an inner node (c_T).
    pub traversal_cost: f32,
    /// SAH cost of testing one primitive (c_I).
    pub intersection_cost: f32,
    /// Nodes with at least this many primitives are built *horizontally* (all threads bin and
    /// partition the one node); smaller nodes are built *vertically* (each subtree is a task).
    pub horizontal_threshold: usize,
    /// How a split is scored: the plain SAH (the default), or one of Moulin and Dutré's
    /// variants for rays that terminate ([`CostModel`]).
    pub cost_model: CostModel,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            bins: 16,
            max_leaf_size: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            horizontal_threshold: 1 << 16,
            cost_model: CostModel::Sah,
        }
    }
}

impl BuildConfig {
    /// Whether the settings are in range, and if not which one is wrong: what [`super::build`]
    /// checks before it starts, for callers that take settings from users.
    ///
    /// ```
    /// use quiver::builders::BuildConfig;
    /// assert!(BuildConfig::default().check().is_ok());
    /// let bad = BuildConfig { bins: 1, ..BuildConfig::default() };
    /// assert!(bad.check().unwrap_err().contains("bins"));
    /// ```
    pub fn check(&self) -> Result<(), String> {
        if !(2..=1024).contains(&self.bins) {
            return Err(format!("bins must be in 2..=1024, got {}", self.bins));
        }
        if self.max_leaf_size < 1 {
            return Err("max_leaf_size must be at least 1, got 0".into());
        }
        for (name, c) in [
            ("traversal_cost", self.traversal_cost),
            ("intersection_cost", self.intersection_cost),
        ] {
            if !(c.is_finite() && c >= 0.0) {
                return Err(format!("{name} must be a finite number >= 0, got {c}"));
            }
        }
        Ok(())
    }
}

/// The item of `all` called `s`; the error names `what` and lists the names.
pub(super) fn by_name<T: Copy>(
    s: &str,
    all: &[T],
    name: fn(T) -> &'static str,
    what: &str,
) -> Result<T, String> {
    all.iter().copied().find(|&x| name(x) == s).ok_or_else(|| {
        let names: Vec<&str> = all.iter().map(|&x| name(x)).collect();
        format!("unknown {what} '{s}': expected one of {}", names.join(", "))
    })
}

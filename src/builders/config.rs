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
    /// Primitives a leaf tests at once, as the SAH counts them: with `g > 1` a leaf of `n`
    /// costs `ceil(n / g)` group tests of [`GROUP_TEST_COST`] each instead of `n` single
    /// tests, so splits that only shave a group's empty lanes are not taken. `0` (the default)
    /// and `1` count primitives one by one, the plain SAH; [`crate::BuildOptions`] turns `0`
    /// into its layout's group (4 for the wide layouts over triangles, whose leaves are SIMD
    /// groups of four).
    pub leaf_group: usize,
}

/// What the SAH charges for testing one SIMD group of a leaf, in units of one primitive test
/// ([`BuildConfig::intersection_cost`]): four triangles tested at once cost more than one
/// and far less than four. Of 1.0, 1.5 and 2.0 measured on the dragon and teapot12
/// (README, "Leaf groups in the SAH"), 1.5 was the best on both together.
pub const GROUP_TEST_COST: f32 = 1.5;

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            bins: 16,
            max_leaf_size: 8,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            horizontal_threshold: 1 << 16,
            cost_model: CostModel::Sah,
            leaf_group: 0,
        }
    }
}

impl BuildConfig {
    /// Whether the settings are in range, and if not which one is wrong: what [`super::build`]
    /// checks before it starts, for callers that take settings from users.
    ///
    /// ```
    /// use quiver_rt::builders::BuildConfig;
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
        if self.leaf_group > MAX_LEAF_GROUP {
            return Err(format!(
                "leaf_group must be at most {MAX_LEAF_GROUP}, got {}",
                self.leaf_group
            ));
        }
        Ok(())
    }

    /// The SAH's count of primitive tests for a leaf of `n` ([`BuildConfig::leaf_group`]).
    ///
    /// ```
    /// use quiver_rt::builders::{BuildConfig, GROUP_TEST_COST};
    /// assert_eq!(BuildConfig::default().tests(5), 5.0);
    /// let grouped = BuildConfig { leaf_group: 4, ..BuildConfig::default() };
    /// assert_eq!(grouped.tests(5), 2.0 * GROUP_TEST_COST);
    /// ```
    #[inline]
    pub fn tests(&self, n: usize) -> f32 {
        // The SAH sweeps call this for every plane: a shift for the power-of-two groups the
        // layouts use, where a division by a runtime `g` showed in the builds' profiles.
        match self.leaf_group {
            0 | 1 => n as f32,
            g if g.is_power_of_two() => {
                ((n + g - 1) >> g.trailing_zeros()) as f32 * GROUP_TEST_COST
            }
            g => n.div_ceil(g) as f32 * GROUP_TEST_COST,
        }
    }
}

/// The widest leaf group [`BuildConfig::check`] accepts.
const MAX_LEAF_GROUP: usize = 64;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tests_counts_whole_groups_for_every_group_width() {
        for g in 0..=MAX_LEAF_GROUP {
            let config = BuildConfig {
                leaf_group: g,
                ..BuildConfig::default()
            };
            for n in 0..300usize {
                let want = match g {
                    0 | 1 => n as f32,
                    _ => (n as f64 / g as f64).ceil() as f32 * GROUP_TEST_COST,
                };
                assert_eq!(config.tests(n), want, "group {g}, {n} primitives");
            }
        }
    }
}

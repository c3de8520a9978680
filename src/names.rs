//! Things chosen by name (builders, cost models, layouts, instruction sets): the one error a
//! name that names nothing gives, [`ParseError`].

use std::fmt;

/// A name that names nothing of its kind: what parsing a
/// [`Builder`](crate::builders::Builder), [`CostModel`](crate::builders::CostModel),
/// [`Layout`](crate::Layout) or [`Isa`](crate::Isa) from a string, or reading
/// [`Isa::ENV`](crate::Isa::ENV), returns. It names the kind, what was given and every name
/// that would have been accepted.
///
/// ```
/// use quiver_rt::names::ParseError;
/// use quiver_rt::Layout;
/// let e: ParseError = "bvh3".parse::<Layout>().unwrap_err();
/// assert_eq!((e.what, e.given.as_str()), ("layout", "bvh3"));
/// assert!(e.expected.contains(&"bvh8-dfs"));
/// assert!(e.to_string().starts_with("unknown layout 'bvh3': expected one of bvh2-dfs, "));
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// The kind of thing named: `"builder"`, `"cost model"`, `"layout"`, `"instruction set"`.
    pub what: &'static str,
    /// What was given.
    pub given: String,
    /// Every accepted name, in the order reports list them.
    pub expected: Vec<&'static str>,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown {} '{}': expected one of {}",
            self.what,
            self.given,
            self.expected.join(", ")
        )
    }
}

impl std::error::Error for ParseError {}

/// The item of `all` called `s`, or the error naming `what` and every name.
pub(crate) fn by_name<T: Copy>(
    s: &str,
    all: &[T],
    name: fn(T) -> &'static str,
    what: &'static str,
) -> Result<T, ParseError> {
    all.iter()
        .copied()
        .find(|&x| name(x) == s)
        .ok_or_else(|| ParseError {
            what,
            given: s.to_string(),
            expected: all.iter().map(|&x| name(x)).collect(),
        })
}

//! SPD `jacks` (being written).

use crate::scene::Scene;

pub(crate) fn make(size: u32) -> Scene {
    super::placeholder("jacks", size)
}

//! SPD `teapot` (being written).

use crate::scene::Scene;

pub(crate) fn make(size: u32) -> Scene {
    super::placeholder("teapot", size)
}

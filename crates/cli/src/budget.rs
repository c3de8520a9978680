//! Memory: the limit a run may use and what each command's work is estimated to take, checked
//! before the work so that a size the CLI accepts either fits or is refused with the estimate.
//!
//! The limit is `--max-memory` if given, else the memory the system has available when the
//! run starts (`MemAvailable` in `/proc/meminfo`, else the physical memory). An estimate is
//! a sum of named parts, each a count times a cost per item: the scene's objects by their
//! sizes in memory ([`scene_bytes`]), build and layout per primitive ([`TRIANGLE_BUILD`],
//! [`MIXED_BUILD`]), and each command's rays, images and repeated builds at costs measured
//! with `/usr/bin/time -f %M` (peak resident memory) and rounded up; the measurements are in
//! README.md. The estimates are upper bounds: the CLI tests check them against the peak
//! memory of real runs.

use crate::commands::Result;
use quiver_scenes::scene::{Census, Object};
use std::sync::OnceLock;

/// The limit a run may use.
#[derive(Clone, Debug)]
pub(crate) struct Limit {
    /// Bytes.
    pub bytes: u64,
    /// Where the figure came from, for messages.
    pub source: String,
}

static LIMIT: OnceLock<Limit> = OnceLock::new();

/// Sets the run's limit: `--max-memory` if given, else what the system has available now.
/// Called once by `main`; later calls change nothing.
pub(crate) fn set_limit(max_memory: Option<u64>) {
    let limit = match max_memory {
        Some(bytes) => Limit {
            bytes,
            source: "--max-memory".into(),
        },
        None => available(),
    };
    let _ = LIMIT.set(limit);
}

/// The run's limit ([`set_limit`]; the available memory if it was never called).
pub(crate) fn limit() -> &'static Limit {
    LIMIT.get_or_init(available)
}

/// The memory available to a new process: `MemAvailable` (what can be allocated without
/// swapping, page cache included), else the physical memory, else no known limit.
fn available() -> Limit {
    let meminfo = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
            let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kb * 1024)
        });
    if let Some(bytes) = meminfo {
        return Limit {
            bytes,
            source: "the memory available when the run started, MemAvailable in /proc/meminfo; \
                     --max-memory sets another limit"
                .into(),
        };
    }
    // SAFETY: `sysconf` only reads system configuration; a failure returns -1, handled below.
    let (pages, page) = unsafe {
        (
            libc::sysconf(libc::_SC_PHYS_PAGES),
            libc::sysconf(libc::_SC_PAGESIZE),
        )
    };
    if pages > 0 && page > 0 {
        return Limit {
            bytes: pages as u64 * page as u64,
            source: "the physical memory; --max-memory sets another limit".into(),
        };
    }
    Limit {
        bytes: u64::MAX,
        source: "no limit known; --max-memory sets one".into(),
    }
}

/// `--max-memory`: a byte count with an optional binary unit, `4G`, `512M`, `1.5GiB`,
/// `100000000` (K, M, G and T are powers of 1024, with or without `B` or `iB`).
pub(crate) fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    if t.starts_with('-') {
        return Err(format!("'{s}' is negative: a size is at least 1 byte"));
    }
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => return Err(format!("'{s}' is not a size (a number and K, M, G or T)")),
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("'{s}' is not a size (a number and K, M, G or T)"))?;
    let bytes = value * (1u64 << shift) as f64;
    if bytes >= u64::MAX as f64 {
        return Err(format!(
            "'{s}' is more than the 16 EiB (2^64 bytes) a size can be"
        ));
    }
    if bytes < 1.0 {
        return Err(format!("'{s}' is less than 1 byte"));
    }
    Ok(bytes as u64)
}

/// A byte count for people: `812 MiB`, `7.3 GiB`, `12 KiB`, `100 bytes`.
pub(crate) fn human(bytes: u64) -> String {
    const GIB: f64 = (1u64 << 30) as f64;
    const MIB: f64 = (1u64 << 20) as f64;
    let b = bytes as f64;
    if b >= GIB {
        format!("{:.1} GiB", b / GIB)
    } else if b >= MIB {
        format!("{:.0} MiB", b / MIB)
    } else if bytes >= 1024 {
        format!("{:.0} KiB", (b / 1024.0).ceil())
    } else if bytes == 1 {
        "1 byte".into()
    } else {
        format!("{bytes} bytes")
    }
}

/// Build and layout per triangle of the triangle path (soups, meshes, patch mode): the
/// largest of every builder and every layout on a 1,000,000-triangle soup (`quiver build
/// soup1000000 --builder B --layout L`: at most 762 MB with the scene's 128 B a triangle,
/// for `aac-fast` and `bvh4-dfs`, so 634 B), rounded up. The default `binned` and `bvh2-dfs`
/// take 275 B.
pub(crate) const TRIANGLE_BUILD: u64 = 680;

/// Build and layout per primitive of the mixed path (spheres, cones and polygons' triangles
/// in curve mode): the largest measured, balls6 in `bvh4-quant` (555 B a sphere with the
/// scene), tree18 with `aac-fast` and `bvh4-dfs` (533 B), gears12 likewise (483 B), less the
/// scene's 80 B an object, rounded up.
pub(crate) const MIXED_BUILD: u64 = 520;

/// Build per instance of an instanced scene: the instance (transform, inverse, bounds, ids),
/// its top-level tree leaf and build records and the scene's hit mapping. `quiver render
/// balls7 --instanced --res 512` (5,380,841 instances) peaks at 4.07 GB with `/usr/bin/time
/// -v`, 773 B an instance with the scene and the render included; rounded up.
pub(crate) const INSTANCE_BUILD: u64 = 1000;

/// A fixed allowance for the program, its thread stacks and allocator slack (an empty run
/// peaks at 5 MB; 64 threads' stacks are 128 MB of address space, little of it resident).
pub(crate) const BASE: u64 = 64 << 20;

/// What a scene of census `c` takes in memory: its objects, their vertex lists (a polygon's
/// vertices, a patch's vertices and normals, each list a heap allocation with its header),
/// and the triangle list a loader or generator builds before its objects.
pub(crate) fn scene_bytes(c: &Census) -> u64 {
    let object = std::mem::size_of::<Object>() as u64;
    let vertex = std::mem::size_of::<glam::Vec3A>() as u64;
    let allocation = 32;
    c.objects() * object
        + c.polygon_vertices * vertex
        + c.patch_vertices * 2 * vertex
        + (c.polygons + 2 * c.patches) * allocation
        + c.triangles * std::mem::size_of::<quiver_rt::Triangle>() as u64
}

/// An estimate: named parts that add up.
pub(crate) struct Estimate {
    /// What is estimated (the command and scene), for the message.
    what: String,
    parts: Vec<(String, u64)>,
}

impl Estimate {
    pub(crate) fn new(what: impl Into<String>) -> Estimate {
        Estimate {
            what: what.into(),
            parts: vec![("the program".into(), BASE)],
        }
    }

    /// Adds a part (none if `bytes` is 0).
    pub(crate) fn add(&mut self, part: impl Into<String>, bytes: u64) -> &mut Self {
        if bytes > 0 {
            self.parts.push((part.into(), bytes));
        }
        self
    }

    pub(crate) fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |sum, (_, b)| sum.saturating_add(*b))
    }

    /// Fails, with the estimate, its parts and the limit, when the estimate passes the limit.
    pub(crate) fn check(&self) -> Result<()> {
        let limit = limit();
        let total = self.total();
        if total <= limit.bytes {
            return Ok(());
        }
        let parts: Vec<String> = self
            .parts
            .iter()
            .skip(1)
            .map(|(what, b)| format!("{what} {}", human(*b)))
            .collect();
        Err(format!(
            "{}: needs about {} [{total} bytes] ({}), more than the {} this run may use ({})",
            self.what,
            human(total),
            parts.join("; "),
            human(limit.bytes),
            limit.source
        )
        .into())
    }
}

/// `n` items, for messages: `1,048,576`.
pub(crate) fn count(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512m"), Ok(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("100000"), Ok(100_000));
        assert_eq!(parse_size("2 TB"), Ok(2 << 40));
        for bad in ["", "G", "4X", "-1G", "0", "0.1", "1e3", "nan"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_size("1"), Ok(1));
        let e = parse_size("99999999T").unwrap_err();
        assert!(e.contains("more than the 16 EiB"), "{e}");
        assert!(parse_size("-1").unwrap_err().contains("negative"));
        assert!(parse_size("0").unwrap_err().contains("less than 1 byte"));
    }

    #[test]
    fn counts_and_sizes_read_well() {
        assert_eq!(count(0), "0");
        assert_eq!(count(1_048_576), "1,048,576");
        assert_eq!(count(999), "999");
        assert_eq!(human(805 << 20), "805 MiB");
        assert_eq!(human((73 << 30) / 10), "7.3 GiB");
        assert_eq!(human(1), "1 byte");
        assert_eq!(human(1000), "1000 bytes");
        assert_eq!(human(1025), "2 KiB");
    }
}

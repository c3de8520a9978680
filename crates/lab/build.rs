//! With the `tinybvh` feature: compiles `ffi/tinybvh_shim.cpp`, quiver-lab's C entry points
//! into tinybvh's CPU layouts, together with tinybvh itself from one `tiny_bvh.h`: the one in
//! the directory `QUIVER_TINYBVH_HEADER_DIR` names (e.g. a newer upstream header, kept outside
//! the repository), else the snapshot the tinybvh-rs crate ships. Which header it was (its
//! path and an FNV-1a hash of its bytes) reaches the crate as `QUIVER_TINYBVH_HEADER` and
//! `QUIVER_TINYBVH_HEADER_HASH`, so the benches can say which tinybvh they timed. Without the
//! feature, nothing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "tinybvh")]
    tinybvh::compile();
}

#[cfg(feature = "tinybvh")]
mod tinybvh {
    use std::path::PathBuf;
    use std::process::Command;

    /// The crate whose `tiny_bvh.h` is the default header (its build flags, `-std=c++20
    /// -march=native`, are the shim's too).
    const CRATE: &str = "tinybvh-rs";

    pub fn compile() {
        println!("cargo:rerun-if-changed=ffi/tinybvh_shim.cpp");
        println!("cargo:rerun-if-env-changed=QUIVER_TINYBVH_HEADER_DIR");
        let header_dir = header_dir();
        let header = header_dir.join("tiny_bvh.h");
        println!("cargo:rerun-if-changed={}", header.display());
        let bytes =
            std::fs::read(&header).unwrap_or_else(|e| panic!("reading {}: {e}", header.display()));
        println!("cargo:rustc-env=QUIVER_TINYBVH_HEADER={}", header.display());
        println!(
            "cargo:rustc-env=QUIVER_TINYBVH_HEADER_HASH={:016x}",
            fnv1a(&bytes)
        );
        cc::Build::new()
            .cpp(true)
            .file("ffi/tinybvh_shim.cpp")
            .include(&header_dir)
            .std("c++20")
            .flag("-march=native")
            // The peer at its best whatever the profile: tinybvh's own builds use -O3.
            .opt_level(3)
            // tiny_bvh.h warns about what it does not use; the shim's own code is small.
            .warnings(false)
            .compile("quiver_tinybvh_shim");
    }

    /// FNV-1a (64 bits) of `bytes`: enough to tell two headers apart in a report.
    fn fnv1a(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })
    }

    /// `QUIVER_TINYBVH_HEADER_DIR` if set (it must hold a `tiny_bvh.h`); else where
    /// tinybvh-rs's `tiny_bvh.h` is: cargo knows where it unpacked the crate, so ask it
    /// (`cargo metadata`, offline: the crate is already there, being built beside us).
    fn header_dir() -> PathBuf {
        if let Ok(dir) = std::env::var("QUIVER_TINYBVH_HEADER_DIR") {
            let dir = PathBuf::from(dir);
            assert!(
                dir.join("tiny_bvh.h").is_file(),
                "QUIVER_TINYBVH_HEADER_DIR={}: no tiny_bvh.h there",
                dir.display()
            );
            return dir;
        }
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let manifest =
            PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("Cargo.toml");
        // Only this target's packages: the others (Windows crates) may never have been fetched.
        let target = std::env::var("TARGET").unwrap();
        // Offline first (the crate is already there); on a fresh machine cargo may not yet
        // have fetched every package the metadata names (other targets' dev-dependencies),
        // and then it may fetch them.
        let metadata = |offline: bool| {
            let mut c = Command::new(&cargo);
            c.args(["metadata", "--format-version", "1"]);
            if offline {
                c.arg("--offline");
            }
            c.args(["--features", "quiver-lab/tinybvh", "--filter-platform"])
                .arg(&target)
                .arg("--manifest-path")
                .arg(&manifest)
                .output()
                .expect("running cargo metadata to find tinybvh-rs")
        };
        let mut out = metadata(true);
        if !out.status.success() {
            out = metadata(false);
        }
        assert!(
            out.status.success(),
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let meta: serde_json::Value =
            serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
        let manifest_path = meta["packages"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|p| p["name"] == CRATE)
            .and_then(|p| p["manifest_path"].as_str())
            .expect("tinybvh-rs among the packages (the feature depends on it)");
        let dir = PathBuf::from(manifest_path)
            .parent()
            .expect("a manifest's directory")
            .join("ffi/tinybvh");
        assert!(
            dir.join("tiny_bvh.h").is_file(),
            "no tiny_bvh.h in {}",
            dir.display()
        );
        dir
    }
}

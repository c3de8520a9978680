//! `examples/c/minimal.c` compiled with the system's C compiler against the static library,
//! run, and its answers compared with the Rust API's for the same rays and closest points:
//! the C side (header, struct layouts, link line) and the Rust side agree. Skipped, with a note, where no `cc`
//! is on the PATH.

use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
use quiver_rt::{BuildOptions, Bvh, Instance, InstanceId, Motion, Ray, RayQuery, World};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The scene of minimal.c: a unit square of two triangles.
const VERTICES: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
const INDICES: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

/// The world of minimal.c: the square in place (mask 1), and moved by (2, 0, -1) (mask 2).
fn world() -> World {
    let mut b = World::builder();
    let g = b.add_mesh(&VERTICES, &INDICES).unwrap();
    b.add_instance(Instance::of(g).mask(1));
    let moved = Affine3A::from_translation(Vec3::new(2.0, 0.0, -1.0));
    b.add_instance(Instance::of(g).transform(moved).mask(2));
    b.build(&BuildOptions::default()).unwrap()
}

/// The directory holding the static library this test build goes with (`target/<profile>`,
/// the parent of the `deps` directory this test runs from). `cargo test` leaves the
/// staticlib there only as the last `cargo build` made it, which may be older than the
/// sources, so it is built here with the same profile (nothing to do when it is current).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().and_then(Path::parent).unwrap().to_path_buf();
    let profile = dir.file_name().unwrap().to_str().unwrap();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .args(["build", "-p", "quiver-capi", "--profile"])
        .arg(if profile == "debug" { "dev" } else { profile })
        .status()
        .unwrap();
    assert!(status.success(), "cargo build -p quiver-capi failed");
    assert!(
        dir.join("libquiver_capi.a").exists(),
        "no libquiver_capi.a in {}",
        dir.display()
    );
    dir
}

/// What one output line says: which scene, the ray, and the hit
/// `(prim, geometry, instance, t, u, v)` or `None` for a miss.
type Line = (String, Ray, Option<(u32, u32, u32, f32, f32, f32)>);

/// Parses a line `SCENE ox oy oz dx dy dz mask time -> miss` or `... -> prim P geometry G
/// instance I t T u U v V`; `None` for other lines (closest points included).
fn parse(line: &str) -> Option<Line> {
    let (ray, hit) = line.split_once(" -> ")?;
    let mut r = ray.split_whitespace();
    let scene = r.next().filter(|&s| s != "point")?.to_string();
    let f: Vec<f32> = r.by_ref().take(6).map(|x| x.parse().unwrap()).collect();
    let mask: u32 = r.next()?.parse().unwrap();
    let time: f32 = r.next()?.parse().unwrap();
    let ray = Ray::new(Vec3A::new(f[0], f[1], f[2]), Vec3A::new(f[3], f[4], f[5]))
        .with_mask(mask)
        .with_time(time);
    if hit == "miss" {
        return Some((scene, ray, None));
    }
    let w: Vec<&str> = hit.split_whitespace().collect();
    let u = |i: usize| w[i].parse::<u32>().unwrap();
    let x = |i: usize| w[i].parse::<f32>().unwrap();
    Some((scene, ray, Some((u(1), u(3), u(5), x(7), x(9), x(11)))))
}

/// What one closest-point line says: the scene, the query `(point, max_distance, time)`, and
/// the answer `(prim, geometry, instance, point, u, v, distance)` or `None` for a miss.
type PointLine = (
    String,
    (Vec3A, f32, f32),
    Option<(u32, u32, u32, Vec3A, f32, f32, f32)>,
);

/// Parses a line `point SCENE px py pz max time -> miss` or `... -> prim P geometry G
/// instance I point X Y Z u U v V distance D`; `None` for other lines.
fn parse_point(line: &str) -> Option<PointLine> {
    let (query, hit) = line.strip_prefix("point ")?.split_once(" -> ")?;
    let mut q = query.split_whitespace();
    let scene = q.next()?.to_string();
    let f: Vec<f32> = q.map(|x| x.parse().unwrap()).collect();
    let query = (Vec3A::new(f[0], f[1], f[2]), f[3], f[4]);
    if hit == "miss" {
        return Some((scene, query, None));
    }
    let w: Vec<&str> = hit.split_whitespace().collect();
    let u = |i: usize| w[i].parse::<u32>().unwrap();
    let x = |i: usize| w[i].parse::<f32>().unwrap();
    let point = Vec3A::new(x(7), x(8), x(9));
    Some((
        scene,
        query,
        Some((u(1), u(3), u(5), point, x(11), x(13), x(15))),
    ))
}

/// minimal.c compiled with `cc` and `flags` against the static library, run; its standard
/// output once it has run to its end and said its answers were as expected. `Err` with a note
/// where it could not be compiled, which the caller decides about.
fn compile_and_run(name: &str, flags: &[&str]) -> Result<String, String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    if Command::new("cc").arg("--version").output().is_err() {
        return Err("no `cc` on the PATH".into());
    }
    let lib = library_dir();
    let exe = std::env::temp_dir().join(format!("quiver_capi_{name}_{}", std::process::id()));
    let cc = Command::new("cc")
        .args(flags)
        .arg(root.join("examples/c/minimal.c"))
        .arg("-I")
        .arg(root.join("include"))
        .arg(lib.join("libquiver_capi.a"))
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&exe)
        .output()
        .unwrap();
    if !cc.status.success() {
        return Err(format!(
            "cc {flags:?} failed:\n{}",
            String::from_utf8_lossy(&cc.stderr)
        ));
    }
    let run = Command::new(&exe)
        .env("ASAN_OPTIONS", "detect_leaks=1:halt_on_error=1")
        .env("UBSAN_OPTIONS", "halt_on_error=1:print_stacktrace=1")
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&exe);
    let stdout = String::from_utf8(run.stdout).unwrap();
    assert!(
        run.status.success(),
        "minimal ({flags:?}) failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("all answers as expected"), "{stdout}");
    Ok(stdout)
}

/// The C example built with AddressSanitizer and UndefinedBehaviorSanitizer (leak checks on)
/// runs clean: no overrun of the buffers the C side hands over or gets back, no leak of a
/// handle freed as the header says, no undefined behaviour in the C caller. Skipped, with a
/// note, where the C compiler has no sanitizer runtime.
#[test]
fn the_c_example_runs_clean_under_sanitizers() {
    let flags = [
        "-g",
        "-fsanitize=address,undefined",
        "-fno-omit-frame-pointer",
    ];
    if let Err(note) = compile_and_run("minimal_asan", &flags) {
        println!("note: the sanitizer build was not run: {note}");
    }
}

#[test]
fn the_c_example_answers_as_the_rust_api() {
    let stdout = match compile_and_run("minimal", &[]) {
        Ok(stdout) => stdout,
        Err(note) if note.starts_with("no `cc`") => {
            println!("note: {note}; the C example was not compiled");
            return;
        }
        Err(failure) => panic!("{failure}"),
    };
    // The C compiler lays the structs out at the sizes the library uses.
    let sizes = format!(
        "sizes QvRay {} QvHit {} QvPointHit {} QvBuildOptions {}",
        size_of::<quiver_capi::QvRay>(),
        size_of::<quiver_capi::QvHit>(),
        size_of::<quiver_capi::QvPointHit>(),
        size_of::<quiver_capi::QvBuildOptions>()
    );
    assert!(stdout.lines().any(|l| l == sizes), "{sizes} in\n{stdout}");
    // qv_bvh_footprint is the Rust footprint's total, for each build minimal.c makes.
    let quant = BuildOptions::fast().layout(quiver_rt::Layout::Bvh4Quant);
    let footprints = format!(
        "footprint bvh8-dfs {} bvh4-quant {}",
        Bvh::from_mesh(&VERTICES, &INDICES)
            .unwrap()
            .footprint()
            .kept,
        Bvh::build_mesh(&VERTICES, &INDICES, &quant)
            .unwrap()
            .footprint()
            .kept
    );
    assert!(
        stdout.lines().any(|l| l == footprints),
        "{footprints} in\n{stdout}"
    );

    let bvh = Bvh::from_mesh(&VERTICES, &INDICES).unwrap();
    let world = world();
    // The edit minimal.c makes: the second square up to z = 0 and seen by every ray.
    let mut edited = self::world();
    let mut e = edited.edit();
    let to = quiver_rt::InstanceId(1);
    e.set_transform(to, Affine3A::from_translation(Vec3::new(2.0, 0.0, 0.0)))
        .unwrap();
    e.set_mask(to, u32::MAX).unwrap();
    e.commit();
    // Then the first square set rising from z = 0 to z = 4 over the shutter.
    let mut moving = edited.clone();
    let rise = Motion::linear(vec![
        Affine3A::IDENTITY,
        Affine3A::from_translation(Vec3::new(0.0, 0.0, 4.0)),
    ]);
    moving.edit().set_motion(InstanceId(0), rise).unwrap();

    let mut counts = [0; 5];
    for (scene, ray, hit) in stdout.lines().filter_map(parse) {
        let want = match scene.as_str() {
            "bvh" => {
                counts[0] += 1;
                bvh.closest_hit(&ray)
                    .map(|h| (h.prim, u32::MAX, u32::MAX, h.t, h.u, h.v))
            }
            "world" | "edited" | "moving" => {
                let (w, k) = match scene.as_str() {
                    "world" => (&world, 1),
                    "edited" => (&edited, 2),
                    _ => (&moving, 3),
                };
                counts[k] += 1;
                w.closest_hit(&ray)
                    .map(|h| (h.prim, h.geometry.0, h.instance.0, h.t, h.u, h.v))
            }
            other => panic!("an unknown scene {other}"),
        };
        assert_eq!(hit, want, "{scene} {ray:?}");
    }
    for (scene, (p, max, time), hit) in stdout.lines().filter_map(parse_point) {
        assert_eq!(scene, "moving");
        counts[4] += 1;
        let want = moving.closest_point_at(p, max, time).map(|h| {
            (
                h.prim,
                h.geometry.0,
                h.instance.0,
                h.point,
                h.u,
                h.v,
                h.distance,
            )
        });
        assert_eq!(hit, want, "point {p} max {max} time {time}");
    }
    assert_eq!(counts, [3, 4, 1, 1, 5], "{stdout}");
}

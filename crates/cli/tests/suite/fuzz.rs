//! Property-based fuzzing of scene validation (proptest): the examples, mutated the way a
//! new user gets a value wrong (wrong types, null, negatives, zeros, huge numbers, scaled
//! values, unknown keys, deep nesting, long strings, removed keys, truncated text). For
//! every mutant, validation must not panic, must return within a time bound and must not
//! allocate past a memory bound; every valid mutant then runs a few steps, which must end
//! finished, stopped, cancelled or refused (exit 0, 3 or 2), never in a panic or a signal
//! (an abort would end this test process).
//!
//! Cases per run: `MPM_FUZZ_CASES` (default 3000, about 15 s on 2 cores); seed: `MPM_FUZZ_SEED` (default fixed, so
//! CI is reproducible). `cargo test -p mpm-cli --test suite fuzz:: -- --nocapture` prints the figures.

use mpm_core::output::NullSink;
use mpm_core::scene::{Limits, Mechanics, parse_scene_value_limited};
use mpm_core::solver::{Control, Progress, RunError, preflight, run_scene};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use serde_json::{Value, json};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Counts live bytes and their peak; refuses (null, so the process aborts with "memory
/// allocation failed") anything that would take the live total past `HARD_CAP`, so a
/// defect cannot take the machine's memory.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
const HARD_CAP: usize = 3 << 30;

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let size = layout.size();
        let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
        if live > HARD_CAP {
            LIVE.fetch_sub(size, Ordering::Relaxed);
            return std::ptr::null_mut();
        }
        PEAK.fetch_max(live, Ordering::Relaxed);
        // SAFETY: forwarded as received.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: forwarded as received.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The tests of this file measure the process's allocations: one at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Bytes allocated past the live total at the start of `f`, at the peak.
fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = f();
    (out, PEAK.load(Ordering::Relaxed).saturating_sub(base))
}

/// Limits of the fuzz runs: the examples fit (cube-drop has 132,651 particles), and the
/// memory bound below follows from them.
fn limits() -> Limits {
    Limits {
        max_particles: 300_000,
        max_grid_nodes: 2_000_000,
        max_frames: 10_000,
        max_store_bytes: 10_000_000_000,
        ..Limits::default()
    }
}

/// Most bytes one validation (with preflight) may allocate under [`limits`].
const VALIDATION_BYTES: usize = 1 << 30;
/// Longest one validation may take.
const VALIDATION_TIME: Duration = Duration::from_secs(5);
/// Steps of the short run of a valid mutant.
const STEPS: u64 = 2;
/// Most quasi-static relaxation iterations per step in the short run.
const RELAX_ITERATIONS: u32 = 200;

fn examples() -> Vec<(String, Value)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut out: Vec<(String, Value)> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            let value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            (name, value)
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// One change to a scene.
#[derive(Clone, Debug)]
enum Mutation {
    /// Replace the value at a path.
    Set(usize, Value),
    /// Multiply the number at a path.
    Scale(usize, f64),
    /// Add a key nobody knows to the object at a path (or its parent).
    UnknownKey(usize),
    /// Remove the key or element at a path.
    Remove(usize),
    /// Wrap the value at a path in `n` arrays.
    Nest(usize, usize),
    /// Cut the JSON text at a fraction of its length.
    Truncate(f64),
}

fn replacement() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(Value::Null),
        Just(json!("text")),
        Just(json!(true)),
        Just(json!([])),
        Just(json!({})),
        Just(json!(0)),
        Just(json!(-1)),
        Just(json!(-1.5)),
        Just(json!(1e300)),
        Just(json!(-1e308)),
        Just(json!(1e-300)),
        Just(json!(4294967295u64)),
        Just(json!(18446744073709551615u64)),
        Just(json!(-9223372036854775808i64)),
        Just(json!([1e308, -1e308, 0])),
        Just(json!("x".repeat(100_000))),
        any::<f64>()
            .prop_filter("finite", |x| x.is_finite())
            .prop_map(|x| json!(x)),
        (0u32..100).prop_map(|x| json!(x)),
    ]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<usize>(), replacement()).prop_map(|(p, v)| Mutation::Set(p, v)),
        4 => (
            any::<usize>(),
            prop_oneof![Just(1e6), Just(1e-6), Just(-1.0), Just(0.0), Just(1e300), Just(10.0)]
        )
            .prop_map(|(p, f)| Mutation::Scale(p, f)),
        1 => any::<usize>().prop_map(Mutation::UnknownKey),
        2 => any::<usize>().prop_map(Mutation::Remove),
        1 => (any::<usize>(), prop_oneof![Just(10usize), Just(200)])
            .prop_map(|(p, n)| Mutation::Nest(p, n)),
        1 => (0.0f64..1.0).prop_map(Mutation::Truncate),
    ]
}

/// Every JSON pointer in a value, the root excluded.
fn pointers(v: &Value, here: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{here}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let p = format!("{here}/{i}");
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        _ => {}
    }
}

/// The scene text after the mutations.
fn mutate(scene: &Value, mutations: &[Mutation]) -> String {
    let mut v = scene.clone();
    let mut truncate = None;
    for m in mutations {
        let mut all = Vec::new();
        pointers(&v, String::new(), &mut all);
        let pick = |i: usize| all[i % all.len()].clone();
        match m {
            Mutation::Set(i, x) => *v.pointer_mut(&pick(*i)).unwrap() = x.clone(),
            Mutation::Scale(i, f) => {
                let slot = v.pointer_mut(&pick(*i)).unwrap();
                if let Some(x) = slot.as_f64() {
                    *slot = serde_json::Number::from_f64(x * f)
                        .map(Value::Number)
                        .unwrap_or(json!(1e308));
                }
            }
            Mutation::UnknownKey(i) => {
                let p = pick(*i);
                let parent = &p[..p.rfind('/').unwrap()];
                if let Some(Value::Object(o)) = v.pointer_mut(parent) {
                    o.insert("bogus_key".into(), json!(1));
                } else if let Some(o) = v.as_object_mut() {
                    o.insert("bogus_key".into(), json!(1));
                }
            }
            Mutation::Remove(i) => {
                let p = pick(*i);
                let (parent, last) = p.rsplit_once('/').unwrap();
                match v.pointer_mut(parent) {
                    Some(Value::Object(o)) => {
                        o.remove(&last.replace("~1", "/").replace("~0", "~"));
                    }
                    Some(Value::Array(a)) => {
                        a.remove(last.parse::<usize>().unwrap());
                    }
                    _ => {}
                }
            }
            Mutation::Nest(i, n) => {
                let slot = v.pointer_mut(&pick(*i)).unwrap();
                let mut x = slot.take();
                for _ in 0..*n {
                    x = Value::Array(vec![x]);
                }
                *slot = x;
            }
            Mutation::Truncate(f) => truncate = Some(*f),
        }
    }
    let text = v.to_string();
    match truncate {
        Some(f) => {
            let mut cut = (text.len() as f64 * f) as usize;
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            text[..cut].to_string()
        }
        None => text,
    }
}

#[derive(Default)]
struct Tally {
    cases: usize,
    invalid: usize,
    valid: usize,
    finished: usize,
    stopped_or_cancelled: usize,
    refused: usize,
    slowest_validation: f64,
    largest_validation: usize,
    slowest_run: f64,
    largest_run: usize,
    slow: Vec<String>,
}

/// Validates and briefly runs one mutant; `Err` describes a defect.
fn check(
    text: &str,
    registry: &mpm_core::plugin::Registry,
    base: &Path,
    tally: &mut Tally,
) -> Result<(), String> {
    tally.cases += 1;
    let start = Instant::now();
    let (validated, bytes) = peak_during(|| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let value: Value = match serde_json::from_str(text) {
                Ok(v) => v,
                Err(_) => return None,
            };
            let v = parse_scene_value_limited(value, registry, base, &limits()).ok()?;
            match preflight(&v) {
                Ok(()) => Some(Ok(v)),
                Err(e) => Some(Err(e)),
            }
        }))
    });
    let elapsed = start.elapsed();
    tally.slowest_validation = tally.slowest_validation.max(elapsed.as_secs_f64());
    tally.largest_validation = tally.largest_validation.max(bytes);
    let validated = validated.map_err(|_| "validation panicked".to_string())?;
    if elapsed > VALIDATION_TIME {
        return Err(format!("validation took {elapsed:?}"));
    }
    if bytes > VALIDATION_BYTES {
        return Err(format!("validation allocated {bytes} bytes"));
    }
    let scene = match validated {
        None => {
            tally.invalid += 1;
            return Ok(());
        }
        Some(Err(RunError::Refused { .. })) => {
            tally.refused += 1;
            return Ok(());
        }
        Some(Err(e)) => return Err(format!("preflight failed operationally: {e}")),
        Some(Ok(scene)) => scene,
    };
    let mut scene = scene;
    // A quasi-static step relaxes for up to max_iterations (a mutant may ask 20,000, seconds
    // a step): the short run caps them, and may then stop on non-convergence (exit 3).
    if let Mechanics::QuasiStatic { max_iterations, .. } = &mut scene.scene.solver.mechanics {
        *max_iterations = (*max_iterations).min(RELAX_ITERATIONS);
    }
    // An implicit step factors its preconditioner every Newton iteration (seconds for the 3D
    // strip): the short run caps Newton and the cuts, and may then stop (exit 3).
    if let Mechanics::Implicit(settings) = &mut scene.scene.solver.mechanics {
        settings.max_newton_iterations = settings.max_newton_iterations.min(3);
        settings.max_cuts = settings.max_cuts.min(1);
    }
    tally.valid += 1;
    let start = Instant::now();
    let (result, bytes) = peak_during(|| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let mut observer = |p: &Progress| {
                if p.step >= STEPS {
                    Control::Cancel
                } else {
                    Control::Continue
                }
            };
            run_scene(&scene, &mut NullSink, &mut observer)
        }))
    });
    let seconds = start.elapsed().as_secs_f64();
    tally.slowest_run = tally.slowest_run.max(seconds);
    if seconds > 2.0 {
        tally.slow.push(format!("{seconds:.1} s"));
    }
    tally.largest_run = tally.largest_run.max(bytes);
    match result.map_err(|_| "the short run panicked".to_string())? {
        Ok(m) if m.outcome == Some(mpm_core::output::Outcome::Finished) => tally.finished += 1,
        Ok(_) => tally.stopped_or_cancelled += 1,
        Err(RunError::Refused { .. }) => tally.refused += 1,
        Err(e) => return Err(format!("the short run failed operationally: {e}")),
    }
    Ok(())
}

#[test]
fn mutated_examples_never_panic_hang_or_exhaust_memory() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cases: u32 = std::env::var("MPM_FUZZ_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(3000);
    let seed: u64 = std::env::var("MPM_FUZZ_SEED")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(24);
    let examples = examples();
    let registry = mpm_cli::default_registry();
    let base: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut seed_bytes = [0u8; 32];
    seed_bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases,
            failure_persistence: None,
            max_shrink_iters: 200,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed_bytes),
    );
    // Quiet the panic messages of cases that are caught (a failure names its case anyway).
    std::panic::set_hook(Box::new(|_| {}));
    let tally = std::cell::RefCell::new(Tally::default());
    let start = Instant::now();
    let strategy = (
        0..examples.len(),
        proptest::collection::vec(mutation(), 1..=3),
    );
    let result = runner.run(&strategy, |(example, mutations)| {
        let text = mutate(&examples[example].1, &mutations);
        let slow = tally.borrow().slow.len();
        let result = check(&text, &registry, &base, &mut tally.borrow_mut());
        if tally.borrow().slow.len() > slow {
            let mut t = tally.borrow_mut();
            let last = t.slow.pop().unwrap_or_default();
            t.slow
                .push(format!("{last}: {} {mutations:?}", examples[example].0));
        }
        result.map_err(|defect| {
            TestCaseError::fail(format!(
                "{}: {defect} after {mutations:?}",
                examples[example].0
            ))
        })
    });
    let _ = std::panic::take_hook();
    let t = tally.into_inner();
    println!(
        "fuzz: {} cases (seed {seed}) in {:.1} s: {} invalid (exit 2), {} valid; short runs: {} \
         finished, {} stopped or cancelled, {} refused; slowest validation {:.3} s, largest {:.1} MB; \
         slowest run {:.3} s, largest {:.1} MB",
        t.cases,
        start.elapsed().as_secs_f64(),
        t.invalid,
        t.valid,
        t.finished,
        t.stopped_or_cancelled,
        t.refused,
        t.slowest_validation,
        t.largest_validation as f64 / 1e6,
        t.slowest_run,
        t.largest_run as f64 / 1e6,
    );
    for s in &t.slow {
        println!("slow short run: {s}");
    }
    if let Err(e) = result {
        panic!("{e}");
    }
    assert!(
        t.valid > 0 && t.invalid > 0,
        "the mutations reach both outcomes"
    );
}

/// The three scenes of issue 24, as a regression floor for the generator above.
#[test]
fn the_three_scenes_of_the_issue_are_refused_quickly_and_cheaply() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let registry = mpm_cli::default_registry();
    let base: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let ex = |name: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(base.join(name)).unwrap()).unwrap()
    };
    let mut a = ex("capillary-cross-section.json");
    let y = a["bodies"][0]["shape"]["box"]["max"][1].as_f64().unwrap();
    a["bodies"][0]["shape"]["box"]["max"][1] = json!(y * 1e6);
    let mut b = ex("vibrating-bar.json");
    b["bodies"][0]["shape"]["box"]["min"][0] = json!(-1e308);
    let mut c = ex("two-disks.json");
    let r = c["bodies"][0]["shape"]["sphere"]["radius"]
        .as_f64()
        .unwrap();
    c["bodies"][0]["shape"]["sphere"]["radius"] = json!(r * 1e6);
    for (scene, path) in [
        (a, "bodies[0].shape.box.max[1]"),
        (b, "bodies[0].shape.box.min[0]"),
        (c, "bodies[0].shape.sphere.radius"),
    ] {
        let start = Instant::now();
        let (result, bytes) =
            peak_during(|| parse_scene_value_limited(scene, &registry, &base, &Limits::default()));
        let elapsed = start.elapsed();
        let issues = result.err().expect("refused").issues;
        assert!(issues.iter().any(|i| i.path == path), "{issues:?}");
        assert!(elapsed < Duration::from_secs(1), "{elapsed:?}");
        assert!(bytes < 10_000_000, "{bytes} bytes");
    }
}

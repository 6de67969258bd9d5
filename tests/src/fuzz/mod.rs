//! A deterministic, seeded mutation fuzzer that runs on stable Rust.
//!
//! One [`FuzzTarget`] per input kind ([`targets`]): the map product, the
//! desktop readers (OBJ/MTL, PLY, the JSON files, images), the core's image
//! views, the renderer, NCC and the relocalizer. [`run`] executes a target's
//! seed corpus (`tests/fuzz/corpus/<target>/`), then mutated inputs: each
//! iteration `i` draws its mutations from `Rng::new(seed ^ hash(target)).fork(i)`
//! ([`mutate::Mutator`]), so one (seed, target, iteration count) always runs the
//! same inputs. An input whose outcome label was not seen before joins the pool
//! that later iterations mutate (a cheap stand-in for coverage feedback).
//!
//! Every execution runs under `catch_unwind`, and a panic hook writes the
//! input being executed to `<crash_dir>/<target>-seed<S>-iter<I>.bin` and
//! names target, seed and iteration on stderr before anything else happens, so
//! a crash is kept also where panics abort (the release profile). A crashing
//! input is replayed with `fuzz --target T --replay FILE`.
//!
//! Used by `tests/src/bin/fuzz.rs` (long runs, `fsw-docs/verification/fuzz.md`)
//! and `tests/tests/integration/fuzz_smoke.rs` (bounded runs in CI).

pub mod corpus;
pub mod mutate;
pub mod targets;

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Once;
use std::time::{Duration, Instant};
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::rng::Rng;

/// What a target made of one input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The API accepted the input (parsed, rendered, matched, relocalized).
    Accepted,
    /// The API rejected it; the label names the error kind (failure code, or
    /// the message with names and numbers blanked).
    Rejected(String),
}

/// Parser targets need at least 10^6 executions in the recorded run; the
/// others (render, NCC, relocalizer) are slower and get fewer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A reader of bytes from storage, files or uplink.
    Parser,
    /// A core stage or the relocalizer driven with arbitrary sizes and values.
    Stage,
}

/// One fuzz target.
pub struct FuzzTarget {
    /// Name, also the corpus directory under `tests/fuzz/corpus/`.
    pub name: &'static str,
    /// Parser or stage.
    pub kind: Kind,
    /// What it drives, one line (for the report).
    pub about: &'static str,
    /// Text format: token- and line-level mutations too.
    pub text: bool,
    /// Tokens of the format, inserted by the mutator.
    pub dict: &'static [&'static str],
    /// Inputs are cut to this length.
    pub max_len: usize,
    /// Extra seed files, relative to the workspace root (the ICD's examples).
    pub extra_seeds: &'static [&'static str],
    /// The target.
    pub run: fn(&Env, &[u8]) -> Verdict,
}

const OBJ_DICT: &[&str] = &[
    "v", "vt", "vn", "f", "o", "g", "s", "l", "mtllib", "usemtl", "newmtl", "map_Kd", "map_kd",
    "-s", "-o", "-mm", "-t", "-clamp", "-bm", "m.mtl", "tex.png", "rock.png", "sand.png", "rock",
    "sand", "#", "/", "//", "-1", "1/1/1", "0", "\\",
];
const PLY_DICT: &[&str] = &[
    "ply",
    "format",
    "ascii",
    "binary_little_endian",
    "binary_big_endian",
    "1.0",
    "element",
    "vertex",
    "face",
    "property",
    "list",
    "uchar",
    "int",
    "uint",
    "float",
    "double",
    "char",
    "short",
    "ushort",
    "int8",
    "uint8",
    "int32",
    "float32",
    "float64",
    "x",
    "y",
    "z",
    "u",
    "v",
    "s",
    "t",
    "red",
    "green",
    "blue",
    "vertex_indices",
    "vertex_index",
    "texcoord",
    "texnumber",
    "comment TextureFile tex.png",
    "comment TextureFile rock.png",
    "end_header",
    "comment",
    "obj_info",
];
const JSON_DICT: &[&str] = &[
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    "\"",
    "null",
    "true",
    "false",
    "\"width\":",
    "\"height\":",
    "\"fx\":",
    "\"fy\":",
    "\"cx\":",
    "\"cy\":",
    "\"baseline_m\":",
    "\"image_size\":",
    "\"left\":",
    "\"right\":",
    "\"K\":",
    "\"dist\":",
    "\"R\":",
    "\"T\":",
    "\"world_from_left\":",
    "\"t\":",
    "\"q\":",
    "\"covariance\":",
    "\"sigma_t_m\":",
    "\"id\":",
    "\"prior\":",
    "\"truth\":",
    "\"calib\":",
    "\"out\":",
    "\"seed\":",
    "\"x\"",
    "[[1,0,0],[0,1,0],[0,0,1]]",
    "1e999",
    "\\u0000",
    "\\ud800",
];
const IMAGE_DICT: &[&str] = &[
    "P5",
    "P2",
    "P6",
    "P3",
    "255",
    "65535",
    "\n",
    "#",
    "IHDR",
    "IDAT",
    "IEND",
    "PLTE",
    "tRNS",
    "II*\0",
    "MM\0*",
    "\u{ff}\u{d8}\u{ff}",
];

/// Every target, parsers first.
pub const TARGETS: &[FuzzTarget] = &[
    FuzzTarget {
        name: "map",
        kind: Kind::Parser,
        about: "`MapView::new_checked` as given and after `map::reseal`; every accessor of an accepted product",
        text: false,
        dict: &["VTSM", "\u{0}\u{0}\u{0}\u{0}"],
        max_len: 1 << 15,
        extra_seeds: &[],
        run: targets::map_product,
    },
    FuzzTarget {
        name: "obj",
        kind: Kind::Parser,
        about: "`io::obj::parse` (geometry) and `MeshData::from_raw`",
        text: true,
        dict: OBJ_DICT,
        max_len: 1 << 14,
        extra_seeds: &["fsw-docs/interfaces/examples/two-pages/m.obj"],
        run: targets::obj,
    },
    FuzzTarget {
        name: "obj_mtl",
        kind: Kind::Parser,
        about: "`io::obj::parse` with MTL and textures, `MeshData::from_raw`, `encode_map`, `new_checked`",
        text: true,
        dict: OBJ_DICT,
        max_len: 1 << 14,
        extra_seeds: &[],
        run: targets::obj_mtl,
    },
    FuzzTarget {
        name: "ply",
        kind: Kind::Parser,
        about: "`io::ply::parse` (ascii, binary LE/BE, TextureFile), `MeshData::from_raw`, `encode_map`, `new_checked`",
        text: true,
        dict: PLY_DICT,
        max_len: 1 << 14,
        extra_seeds: &[],
        run: targets::ply,
    },
    FuzzTarget {
        name: "calib",
        kind: Kind::Parser,
        about: "`io::calib::parse_calib_any` (rectified and OpenCV forms), `Calib::rig`",
        text: true,
        dict: JSON_DICT,
        max_len: 1 << 12,
        extra_seeds: &["fsw-docs/interfaces/examples/calib-opencv.json"],
        run: targets::calib,
    },
    FuzzTarget {
        name: "prior",
        kind: Kind::Parser,
        about: "`io::json::parse_pose_json` (prior.json / truth.json), `PoseJson::pose`",
        text: true,
        dict: JSON_DICT,
        max_len: 1 << 12,
        extra_seeds: &[],
        run: targets::prior,
    },
    FuzzTarget {
        name: "result",
        kind: Kind::Parser,
        about: "`io::json::parse_result` (result.json)",
        text: true,
        dict: JSON_DICT,
        max_len: 1 << 12,
        extra_seeds: &[],
        run: targets::result,
    },
    FuzzTarget {
        name: "pairs",
        kind: Kind::Parser,
        about: "pairs.jsonl lines as `relocalize --pairs` reads them (`cli::batch::PairSpec`)",
        text: true,
        dict: JSON_DICT,
        max_len: 1 << 12,
        extra_seeds: &["fsw-docs/interfaces/examples/pairs.jsonl"],
        run: targets::pairs,
    },
    FuzzTarget {
        name: "image",
        kind: Kind::Parser,
        about: "`io::image::decode_gray` (PNG with CRCs recomputed, PGM/PPM, JPEG, TIFF), `Gray8::view`",
        text: false,
        dict: IMAGE_DICT,
        max_len: 1 << 13,
        extra_seeds: &[
            "fsw-docs/interfaces/examples/two-pages/rock.png",
            "fsw-docs/interfaces/examples/two-pages/sand.png",
        ],
        run: targets::image,
    },
    FuzzTarget {
        name: "image_view",
        kind: Kind::Stage,
        about: "`ImageView::new` / `ImageViewMut::new` (8 and 16 bit) with any size, stride and length; `get`, `row`, `sub`, `Rect::intersect`, `set`, `row_mut`",
        text: false,
        dict: &[],
        max_len: 256,
        extra_seeds: &[],
        run: targets::image_view,
    },
    FuzzTarget {
        name: "render",
        kind: Kind::Stage,
        about: "`raster::render_window` on a parsed map (tiny map, or the input's own after reseal) with any camera, pose, window and buffer length; `raster::template_mask` with any size",
        text: false,
        dict: &[],
        max_len: 1 << 15,
        extra_seeds: &[],
        run: targets::render,
    },
    FuzzTarget {
        name: "ncc",
        kind: Kind::Stage,
        about: "`ncc::match_template_with`: any template, mask, image and search sizes, contents, filter, mode, `SearchConfig`, short scratch",
        text: false,
        dict: &[],
        max_len: 256,
        extra_seeds: &[],
        run: targets::ncc,
    },
    FuzzTarget {
        name: "reloc",
        kind: Kind::Stage,
        about: "`reloc::Setup` → `build` → `run_to_completion` with random and corrupted frames, priors (NaN included) and parameters",
        text: false,
        dict: &[],
        max_len: 256,
        extra_seeds: &[],
        run: targets::reloc,
    },
];

/// The target named `name`.
pub fn target(name: &str) -> Option<&'static FuzzTarget> {
    TARGETS.iter().find(|t| t.name == name)
}

/// Fixed inputs the targets share: a directory with the textures the mesh
/// readers may name, the tiny map product, and a rendered stereo pair of it.
pub struct Env {
    /// Working directory of this environment (removed on drop).
    pub dir: PathBuf,
    /// The tiny map product ([`corpus::tiny_map`]).
    pub map: Vec<u8>,
    /// Rig of the relocalization target ([`targets::small_rig`]).
    pub rig: StereoRig,
    /// Pose the pair was rendered from.
    pub truth: Pose,
    /// Left image, `rig.cam` sized.
    pub left: Vec<u8>,
    /// Right image.
    pub right: Vec<u8>,
    /// Relocalization parameters ([`targets::reloc_params`]).
    pub params: vtsm_core::config::Params,
}

impl Env {
    /// A new environment in a fresh directory under the system temporary directory.
    ///
    /// # Errors
    /// The directory or its texture files cannot be written.
    pub fn new(tag: &str) -> std::io::Result<Self> {
        // A memory file system where there is one: the obj_mtl target writes a file per input.
        let shm = Path::new("/dev/shm");
        let base = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("vtsm-fuzz-{}-{tag}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        for (name, bytes) in corpus::textures() {
            std::fs::write(dir.join(name), bytes)?;
        }
        let map = corpus::tiny_map();
        let rig = targets::small_rig();
        let truth = crate::testkit::camera_pose(0.3, 0.0);
        let (left, right) = corpus::render_pair(&map, &rig, &truth);
        Ok(Self {
            dir,
            map,
            rig,
            truth,
            left,
            right,
            params: targets::reloc_params(),
        })
    }
}

impl Drop for Env {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// How long to run a target.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Executions (corpus included).
    pub iters: u64,
    /// Stop earlier after this much time.
    pub time: Option<Duration>,
}

/// A crash: what panicked, where the input was written.
#[derive(Clone, Debug)]
pub struct Crash {
    /// Iteration (0-based execution index).
    pub iter: u64,
    /// Panic message.
    pub message: String,
    /// File holding the input.
    pub file: PathBuf,
}

/// What a run of one target did.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    /// Executions.
    pub execs: u64,
    /// Accepted inputs.
    pub accepted: u64,
    /// Rejected inputs.
    pub rejected: u64,
    /// Executions per outcome label (`accepted`, or the rejection label).
    pub outcomes: BTreeMap<String, u64>,
    /// Crashes (the run stops at the first).
    pub crashes: Vec<Crash>,
    /// Wall time.
    pub elapsed: Duration,
    /// Seed corpus size.
    pub corpus: usize,
    /// Pool size at the end (corpus plus inputs with new outcomes).
    pub pool: usize,
}

impl Stats {
    /// Executions per second.
    pub fn rate(&self) -> f64 {
        self.execs as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
    /// Distinct rejection labels.
    pub fn distinct_errors(&self) -> usize {
        self.outcomes.keys().filter(|k| *k != "accepted").count()
    }
}

struct Current {
    active: bool,
    target: &'static str,
    seed: u64,
    iter: u64,
    input: Vec<u8>,
    crash_dir: PathBuf,
    written: Option<PathBuf>,
}

thread_local! {
    static CURRENT: RefCell<Current> = RefCell::new(Current {
        active: false,
        target: "",
        seed: 0,
        iter: 0,
        input: Vec::new(),
        crash_dir: PathBuf::new(),
        written: None,
    });
}

static HOOK: Once = Once::new();

fn crash_file(dir: &Path, target: &str, seed: u64, iter: u64) -> PathBuf {
    dir.join(format!("{target}-seed{seed}-iter{iter}.bin"))
}

/// Install (once) the panic hook that saves the input being executed.
fn install_hook() {
    HOOK.call_once(|| {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            CURRENT.with(|c| {
                let Ok(mut c) = c.try_borrow_mut() else {
                    return;
                };
                if !c.active {
                    return;
                }
                let file = crash_file(&c.crash_dir, c.target, c.seed, c.iter);
                let _ = std::fs::create_dir_all(&c.crash_dir);
                let saved = std::fs::write(&file, &c.input).is_ok();
                eprintln!(
                    "FUZZ CRASH target={} seed={} iter={} input={}{}\n  replay: cargo run --release -p vtsm-tests --bin fuzz -- --target {} --replay {}",
                    c.target,
                    c.seed,
                    c.iter,
                    file.display(),
                    if saved { "" } else { " (could not be written)" },
                    c.target,
                    file.display()
                );
                c.written = Some(file);
            });
            prev(info);
        }));
    });
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

/// Run `t` once on `input` under `catch_unwind`; `Err` is the panic message.
///
/// # Errors
/// The target panicked.
pub fn execute(t: &FuzzTarget, env: &Env, input: &[u8]) -> Result<Verdict, String> {
    install_hook();
    catch_unwind(AssertUnwindSafe(|| (t.run)(env, input))).map_err(|p| panic_message(&*p))
}

fn name_hash(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A draw in `0..n` for iteration `i`, independent of the mutator's stream.
fn rng_pick(base: Rng, i: u64, n: u32) -> usize {
    base.fork(i).fork(0x706f_6f6c).below(n) as usize
}

/// Largest pool of inputs that produced new outcomes.
const POOL_CAP: usize = 256;

/// Run `t`: the seed corpus first, then mutated inputs, until `limits`.
/// Stops at the first crash (its input is written under `crash_dir`).
pub fn run(
    t: &FuzzTarget,
    corpus: &[Vec<u8>],
    env: &Env,
    seed: u64,
    limits: Limits,
    crash_dir: &Path,
) -> Stats {
    install_hook();
    let start = Instant::now();
    let base = Rng::new(seed ^ name_hash(t.name));
    let mut pool: Vec<Vec<u8>> = corpus.to_vec();
    if pool.is_empty() {
        pool.push(Vec::new());
    }
    let mut stats = Stats {
        corpus: corpus.len(),
        ..Stats::default()
    };
    let mut input = Vec::new();
    for i in 0..limits.iters {
        if i % 64 == 0 {
            if let Some(tl) = limits.time {
                if start.elapsed() >= tl {
                    break;
                }
            }
        }
        input.clear();
        let idx = i as usize;
        let mutated = idx >= corpus.len();
        if mutated {
            let mut rng = base.fork(i);
            let k = rng.below(pool.len() as u32) as usize;
            input.extend_from_slice(&pool[k]);
            mutate::Mutator::new(rng, &pool, t.dict, t.text, t.max_len).mutate(&mut input);
        } else {
            input.extend_from_slice(&corpus[idx]);
        }
        CURRENT.with(|c| {
            let mut c = c.borrow_mut();
            c.active = true;
            c.target = t.name;
            c.seed = seed;
            c.iter = i;
            c.input.clear();
            c.input.extend_from_slice(&input);
            c.crash_dir = crash_dir.to_path_buf();
            c.written = None;
        });
        let r = catch_unwind(AssertUnwindSafe(|| (t.run)(env, &input)));
        let written = CURRENT.with(|c| {
            let mut c = c.borrow_mut();
            c.active = false;
            c.written.take()
        });
        stats.execs += 1;
        match r {
            Ok(v) => {
                let label = match v {
                    Verdict::Accepted => {
                        stats.accepted += 1;
                        "accepted".to_string()
                    }
                    Verdict::Rejected(l) => {
                        stats.rejected += 1;
                        l
                    }
                };
                let accepted = label == "accepted";
                let n = stats.outcomes.entry(label).or_insert(0);
                *n += 1;
                if mutated && (*n == 1 || (accepted && rng_pick(base, i, 8) == 0)) {
                    // New outcomes join the pool; accepted inputs join it or
                    // replace a mutated member, so the pool keeps valid inputs
                    // whose neighbourhood reaches past the first checks.
                    if pool.len() < POOL_CAP {
                        pool.push(input.clone());
                    } else if accepted {
                        let free = POOL_CAP - corpus.len().min(POOL_CAP - 1);
                        let k = POOL_CAP - free + rng_pick(base, i ^ (1 << 63), free as u32);
                        pool[k].clone_from(&input);
                    }
                }
            }
            Err(p) => {
                let file = written.unwrap_or_else(|| crash_file(crash_dir, t.name, seed, i));
                stats.crashes.push(Crash {
                    iter: i,
                    message: panic_message(&*p),
                    file,
                });
                break;
            }
        }
    }
    stats.elapsed = start.elapsed();
    stats.pool = pool.len();
    stats
}

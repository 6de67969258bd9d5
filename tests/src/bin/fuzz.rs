//! Run the seeded mutation fuzzer (`vtsm_tests::fuzz`) for a number of
//! executions or a time per target, print what it did, and optionally write
//! the report `fsw-docs/verification/fuzz.md`.
//!
//! ```text
//! cargo run --release -p vtsm-tests --bin fuzz -- --target all --iters 1000000 \
//!     --stage-iters 20000 --seed 1 --jobs 2 --write fsw-docs/verification/fuzz.md
//! cargo run --release -p vtsm-tests --bin fuzz -- --target obj --replay target/fuzz-crashes/obj-seed1-iter42.bin
//! cargo run --release -p vtsm-tests --bin fuzz -- --make-corpus tests/fuzz/corpus
//! ```
//!
//! Options: `--target NAME[,NAME..]|all|parsers|stages`, `--iters N` (per target),
//! `--stage-iters N` (per stage target; default `--iters`), `--iters-for NAME=N`
//! (one target; repeatable), `--seconds T` (cap
//! per target), `--seed S`, `--jobs J` (targets run in parallel, each on one
//! thread, in the order given; results do not depend on it; the report lists
//! them in the order of `fuzz::TARGETS`), `--corpus DIR`, `--crash-dir DIR`,
//! `--write FILE`, `--verbose` (every outcome label). Exit code 1 when a target
//! crashed; the crashing input is in the crash directory. In the release
//! profile a panic aborts the process after the input is written.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Duration;
use vtsm_tests::fuzz::{self, corpus, Env, FuzzTarget, Kind, Limits, Stats, TARGETS};

struct Opts {
    targets: Vec<&'static FuzzTarget>,
    iters: u64,
    stage_iters: Option<u64>,
    iters_for: Vec<(String, u64)>,
    seconds: Option<f64>,
    seed: u64,
    jobs: usize,
    corpus: PathBuf,
    crash_dir: PathBuf,
    write: Option<PathBuf>,
    replay: Option<PathBuf>,
    make_corpus: Option<PathBuf>,
    verbose: bool,
}

fn usage(msg: &str) -> ! {
    eprintln!("fuzz: {msg}");
    eprintln!(
        "usage: fuzz [--target NAME[,NAME..]|all|parsers|stages] [--iters N] [--stage-iters N] [--iters-for NAME=N].. \
         [--seconds T] [--seed S] [--jobs J] [--corpus DIR] [--crash-dir DIR] [--write FILE] \
         [--verbose] | --target NAME --replay FILE | --make-corpus DIR"
    );
    eprintln!(
        "targets: {}",
        TARGETS
            .iter()
            .map(|t| t.name)
            .collect::<Vec<_>>()
            .join(", ")
    );
    std::process::exit(2)
}

fn parse_args(args: &[String]) -> Opts {
    let root = vtsm_tests::workspace_root();
    let mut o = Opts {
        targets: TARGETS.iter().collect(),
        iters: 10_000,
        stage_iters: None,
        iters_for: Vec::new(),
        seconds: None,
        seed: 1,
        jobs: 1,
        corpus: root.join("tests/fuzz/corpus"),
        crash_dir: root.join("target/fuzz-crashes"),
        write: None,
        replay: None,
        make_corpus: None,
        verbose: false,
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || {
            it.next()
                .cloned()
                .unwrap_or_else(|| usage(&format!("{a} needs a value")))
        };
        let num = |s: String| -> u64 {
            s.replace('_', "")
                .parse()
                .unwrap_or_else(|_| usage(&format!("{a}: `{s}` is not a number")))
        };
        match a.as_str() {
            "--target" => {
                let v = val();
                o.targets = match v.as_str() {
                    "all" => TARGETS.iter().collect(),
                    "parsers" => TARGETS.iter().filter(|t| t.kind == Kind::Parser).collect(),
                    "stages" => TARGETS.iter().filter(|t| t.kind == Kind::Stage).collect(),
                    list => list
                        .split(',')
                        .map(|n| {
                            fuzz::target(n.trim())
                                .unwrap_or_else(|| usage(&format!("unknown target `{n}`")))
                        })
                        .collect(),
                };
            }
            "--iters" => o.iters = num(val()),
            "--stage-iters" => o.stage_iters = Some(num(val())),
            "--iters-for" => {
                let v = val();
                let Some((name, n)) = v.split_once('=') else {
                    usage(&format!("--iters-for: `{v}` is not NAME=N"));
                };
                if fuzz::target(name).is_none() {
                    usage(&format!("--iters-for: unknown target `{name}`"));
                }
                o.iters_for.push((name.to_string(), num(n.to_string())));
            }
            "--seconds" => {
                let v = val();
                o.seconds = Some(
                    v.parse()
                        .unwrap_or_else(|_| usage(&format!("--seconds: `{v}` is not a number"))),
                );
            }
            "--seed" => o.seed = num(val()),
            "--jobs" => o.jobs = num(val()).max(1) as usize,
            "--corpus" => o.corpus = PathBuf::from(val()),
            "--crash-dir" => o.crash_dir = PathBuf::from(val()),
            "--write" => o.write = Some(PathBuf::from(val())),
            "--replay" => o.replay = Some(PathBuf::from(val())),
            "--make-corpus" => o.make_corpus = Some(PathBuf::from(val())),
            "--verbose" | "-v" => o.verbose = true,
            "--help" | "-h" => usage("help"),
            other => usage(&format!("unknown argument `{other}`")),
        }
    }
    o
}

fn command_out(cmd: &str, args: &[&str]) -> String {
    std::process::Command::new(cmd)
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".to_string())
}

fn limits_for(o: &Opts, t: &FuzzTarget) -> Limits {
    let by_name = o.iters_for.iter().rev().find(|(n, _)| n == t.name);
    Limits {
        iters: match (by_name, t.kind) {
            (Some((_, n)), _) => *n,
            (None, Kind::Parser) => o.iters,
            (None, Kind::Stage) => o.stage_iters.unwrap_or(o.iters),
        },
        time: o.seconds.map(Duration::from_secs_f64),
    }
}

fn run_all(o: &Opts) -> Vec<Stats> {
    let root = vtsm_tests::workspace_root();
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Stats>>> = Mutex::new(vec![None; o.targets.len()]);
    std::thread::scope(|s| {
        for j in 0..o.jobs.min(o.targets.len()) {
            let (next, results, root) = (&next, &results, &root);
            s.spawn(move || {
                let env = Env::new(&format!("job{j}")).expect("fuzz environment");
                loop {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(t) = o.targets.get(k) else { break };
                    let seeds = corpus::load(t, &o.corpus, root);
                    let st = fuzz::run(t, &seeds, &env, o.seed, limits_for(o, t), &o.crash_dir);
                    print_line(t, &st, o.verbose);
                    results.lock().expect("results")[k] = Some(st);
                }
            });
        }
    });
    results
        .into_inner()
        .expect("results")
        .into_iter()
        .map(Option::unwrap_or_default)
        .collect()
}

fn print_line(t: &FuzzTarget, s: &Stats, verbose: bool) {
    println!(
        "{:<11} execs {:>9}  {:>9.0}/s  accepted {:>8}  rejected {:>9}  distinct errors {:>4}  pool {:>3}  crashes {}",
        t.name,
        s.execs,
        s.rate(),
        s.accepted,
        s.rejected,
        s.distinct_errors(),
        s.pool,
        s.crashes.len()
    );
    for c in &s.crashes {
        println!(
            "  CRASH at iteration {}: {}\n  input: {}",
            c.iter,
            c.message,
            c.file.display()
        );
    }
    if verbose {
        for (label, n) in &s.outcomes {
            println!("    {n:>9}  {label}");
        }
    }
}

fn markdown(o: &Opts, args: &[String], stats: &[Stats], start: &str, load0: &str) -> String {
    let mut s = String::new();
    let order = |t: &FuzzTarget| TARGETS.iter().position(|x| x.name == t.name);
    let mut rows: Vec<(&FuzzTarget, &Stats)> =
        o.targets.iter().copied().zip(stats.iter()).collect();
    rows.sort_by_key(|(t, _)| order(t));
    let cmd = format!(
        "cargo run --release -p vtsm-tests --bin fuzz -- {}",
        args.join(" ")
    );
    s.push_str("# Fuzzing record\n\n");
    s.push_str(
        "Generated by the command below (`tests/src/bin/fuzz.rs`); do not edit by hand.\n\
         The fuzzer (`tests/src/fuzz/`) is a deterministic seeded mutation fuzzer on\n\
         stable Rust: byte mutations (bit flips, byte sets, interesting values, inserts,\n\
         deletes, copies, splices from the corpus, truncation) and, for text formats,\n\
         number-token replacement (`1e300`, `NaN`, `-0`, huge integers, ...), keyword\n\
         insertion and line duplication; inputs with a new outcome join the pool that\n\
         later iterations mutate. Every execution runs under `catch_unwind` with a panic\n\
         hook that writes the input; the release profile has `overflow-checks = true`,\n\
         so integer overflow is a crash too. Seed corpora: `tests/fuzz/corpus/<target>/`\n\
         and the examples of `fsw-docs/interfaces/examples/`. CI runs every target for a\n\
         bounded number of executions (`tests/tests/integration/fuzz_smoke.rs`).\n\n",
    );
    s.push_str(&format!("Command: `{cmd}`\n\n"));
    s.push_str(&format!(
        "| run | |\n|---|---|\n| date | {start} |\n| commit | `{}` |\n| machine | {} ({} hardware threads), load {} at start, {} at end |\n| compiler | {} |\n| seed | {} |\n| jobs | {} |\n\n",
        command_out("git", &["rev-parse", "--short=12", "HEAD"]),
        vtsm_sim::cli::bench::cpu_model(),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        load0,
        vtsm_sim::cli::bench::loadavg(),
        command_out("rustc", &["--version"]),
        o.seed,
        o.jobs
    ));
    s.push_str("| target | kind | executions | seconds | exec/s | accepted | rejected | distinct errors | crashes |\n");
    s.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (t, st) in &rows {
        s.push_str(&format!(
            "| `{}` | {} | {} | {:.1} | {:.0} | {} | {} | {} | {} |\n",
            t.name,
            match t.kind {
                Kind::Parser => "parser",
                Kind::Stage => "stage",
            },
            vtsm_sim::cli::bench::count(st.execs),
            st.elapsed.as_secs_f64(),
            st.rate(),
            vtsm_sim::cli::bench::count(st.accepted),
            vtsm_sim::cli::bench::count(st.rejected),
            st.distinct_errors(),
            st.crashes.len()
        ));
    }
    let total: u64 = stats.iter().map(|s| s.execs).sum();
    let crashes: usize = stats.iter().map(|s| s.crashes.len()).sum();
    s.push_str(&format!(
        "\nTotal: {} executions, {} crashes.\n\n",
        vtsm_sim::cli::bench::count(total),
        crashes
    ));
    s.push_str("## Targets\n\n| target | drives |\n|---|---|\n");
    for (t, _) in &rows {
        s.push_str(&format!(
            "| `{}` | {} |\n",
            t.name,
            t.about.replace('|', "\\|")
        ));
    }
    s.push_str(
        "\n## Outcomes\n\nThe most frequent outcome labels per target (a failure code, or the\n\
         reader's message with quoted text and numbers blanked; `accepted` when the\n\
         input was taken).\n",
    );
    for (t, st) in &rows {
        let mut v: Vec<(&String, &u64)> = st.outcomes.iter().collect();
        v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        s.push_str(&format!(
            "\n`{}` ({} labels):\n\n| executions | outcome |\n|---:|---|\n",
            t.name,
            v.len()
        ));
        for (label, n) in v.iter().take(12) {
            let l = label.replace('|', "\\|").replace('`', "'");
            s.push_str(&format!(
                "| {} | {} |\n",
                vtsm_sim::cli::bench::count(**n),
                l
            ));
        }
        if v.len() > 12 {
            let rest: u64 = v.iter().skip(12).map(|(_, n)| **n).sum();
            s.push_str(&format!(
                "| {} | ({} other labels) |\n",
                vtsm_sim::cli::bench::count(rest),
                v.len() - 12
            ));
        }
    }
    s
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let o = parse_args(&args);
    if let Some(dir) = &o.make_corpus {
        match corpus::generate(dir) {
            Ok(n) => println!("wrote {n} seed files under {}", dir.display()),
            Err(e) => {
                eprintln!("fuzz: cannot write the corpus: {e}");
                std::process::exit(2);
            }
        }
        return;
    }
    if let Some(file) = &o.replay {
        let [t] = o.targets.as_slice() else {
            usage("--replay needs one --target");
        };
        let input =
            std::fs::read(file).unwrap_or_else(|e| usage(&format!("{}: {e}", file.display())));
        let env = Env::new("replay").expect("fuzz environment");
        match fuzz::execute(t, &env, &input) {
            Ok(v) => println!("{}: {v:?}", t.name),
            Err(m) => {
                println!("{}: CRASH: {m}", t.name);
                std::process::exit(1);
            }
        }
        return;
    }
    let start = vtsm_sim::cli::bench::utc_now();
    let load0 = vtsm_sim::cli::bench::loadavg();
    let stats = run_all(&o);
    let crashes: usize = stats.iter().map(|s| s.crashes.len()).sum();
    let total: u64 = stats.iter().map(|s| s.execs).sum();
    println!("total: {total} executions, {crashes} crashes");
    if let Some(path) = &o.write {
        let text = markdown(&o, &args, &stats, &start, &load0);
        if let Err(e) = std::fs::write(path, text) {
            eprintln!("fuzz: cannot write {}: {e}", path.display());
            std::process::exit(2);
        }
        println!("wrote {}", path.display());
    }
    if crashes > 0 {
        std::process::exit(1);
    }
}

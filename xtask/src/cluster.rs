//! `cargo xtask cluster`: split renders on a real Slurm cluster, end to end.
//!
//! Brings up a one-node Slurm cluster on this machine from Debian's packages (installed with
//! apt when missing): `munged`, `slurmctld` and `slurmd` in the foreground as children of this
//! process, on 127.0.0.1 with free ports, with a generated munge key, `slurm.conf`, state,
//! spool and logs in a temporary directory, and no cgroups (`proctrack/linuxproc`,
//! `task/none`). Then it submits the README's job-array script — the text between its
//! `slurm-job-array` markers, unchanged, its settings in the environment — and checks:
//!
//! 1. 4 tasks of 2 passes each, merged with `beamlight merge --passes 0..8`, equal a one-go
//!    render of 8 passes bit for bit, every layer;
//! 2. the same array submitted on hold with task 2 cancelled (`scancel`) before the rest is
//!    released: the merge is refused, naming passes 4..6 as missing; after resubmitting only
//!    `--array=2` it succeeds and equals the one-go render.
//!
//! The cluster is torn down at the end, after a failure too (the [`Cluster`] guard's `Drop`:
//! jobs cancelled, daemons stopped; the directory is removed after a run that passed, unless
//! `--keep`, and kept with its logs after one that failed). A daemon that does not come up
//! fails the run with the tail of its log.
use anyhow::{Context, Result, bail};
use std::{
    path::{Path, PathBuf},
    process::{Child, Command, Output, Stdio},
    time::{Duration, Instant},
};

const SCENE: &str = "assets/scenes/cornell_fog.toml";
const RENDER_ARGS: &str = "--method vbl --backend cpu --width 32 --height 32";
const TASKS: u64 = 4;
const PER_TASK: u64 = 2;
/// The array task that scenario 2 cancels.
const CANCELLED: u64 = 2;
const NODE: &str = "beamlight0";
const BEGIN: &str = "<!-- slurm-job-array:begin";
const END: &str = "<!-- slurm-job-array:end";

pub fn main(root: &Path, args: &[String]) -> Result<()> {
    let mut keep = false;
    for a in args {
        match a.as_str() {
            "--keep" => keep = true,
            "-h" | "--help" => {
                println!("usage: cargo xtask cluster [--keep]   (--keep: leave the cluster's directory and logs)");
                return Ok(());
            }
            other => bail!("cluster: unknown argument '{other}' (usage: cargo xtask cluster [--keep])"),
        }
    }
    let is_root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0\n"));
    if !is_root {
        bail!("cluster: run it as root (it installs packages and runs slurmd, which starts jobs as their users)");
    }
    ensure_installed()?;
    let script = job_script(&std::fs::read_to_string(root.join("README.md")).context("reading README.md")?)?;
    let beamlight = build_beamlight(root)?;
    let t0 = Instant::now();
    let mut cluster = Cluster::start(keep)?;
    let up = t0.elapsed();
    let script_path = cluster.dir.join("render_array.sh");
    std::fs::write(&script_path, &script)?;
    println!(
        "job script: the README's, {} lines, written unchanged to {}",
        script.lines().count(),
        script_path.display()
    );
    let scene = root.join(SCENE);
    let total = TASKS * PER_TASK;

    // The one-go render both scenarios compare against.
    let whole = cluster.dir.join("whole.exr");
    let t = Instant::now();
    run_quiet(
        Command::new(&beamlight)
            .arg("render")
            .arg(&scene)
            .arg("-o")
            .arg(&whole)
            .args(["--passes", &total.to_string()])
            .args(RENDER_ARGS.split_whitespace()),
    )?;
    println!(
        "one-go render: passes 0..{total} -> {} ({:.1} s)",
        whole.display(),
        t.elapsed().as_secs_f64()
    );

    let job = Job {
        cluster: &cluster,
        script: &script_path,
        beamlight: &beamlight,
        scene: &scene,
    };

    // Scenario 1: the whole array, merged, equals the one-go render.
    let t1 = Instant::now();
    println!("\n== scenario 1: {TASKS} tasks of {PER_TASK} passes, merged");
    let out = cluster.dir.join("parts1");
    let id = job.submit(&format!("0-{}", TASKS - 1), &out, false)?;
    cluster.wait(&id)?;
    cluster.expect_states(
        &id,
        &(0..TASKS).map(|t| (t, Some("COMPLETED"))).collect::<Vec<_>>(),
        &out,
    )?;
    let merged = cluster.dir.join("merged1.exr");
    let o = merge(&beamlight, &out, total, &merged)?;
    if !o.status.success() {
        bail!(
            "merge of the complete array failed:\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    print!("{}", indent(&String::from_utf8_lossy(&o.stderr)));
    println!("{}", same_bits(&merged, &whole)?);
    let s1 = t1.elapsed();

    // Scenario 2: one task cancelled, the merge refused, that range resubmitted.
    let t2 = Instant::now();
    println!("\n== scenario 2: task {CANCELLED} cancelled, then resubmitted alone");
    let out = cluster.dir.join("parts2");
    let id = job.submit(&format!("0-{}", TASKS - 1), &out, true)?;
    cluster.run(cluster.cmd("scancel").arg(format!("{id}_{CANCELLED}")))?;
    // A pending array task that is cancelled leaves the array: Slurm keeps no record of it.
    let queued = cluster.tasks(&id)?;
    let others: Vec<u64> = (0..TASKS).filter(|&t| t != CANCELLED).collect();
    if queued != others {
        bail!("after scancel {id}_{CANCELLED}, the array's queued tasks are {queued:?}, expected {others:?}");
    }
    println!("  queued tasks of job {id}: {queued:?} (task {CANCELLED} cancelled before it started)");
    cluster.run(cluster.cmd("scontrol").args(["release", &id]))?;
    cluster.wait(&id)?;
    let states: Vec<(u64, Option<&str>)> = (0..TASKS)
        .map(|t| (t, (t != CANCELLED).then_some("COMPLETED")))
        .collect();
    cluster.expect_states(&id, &states, &out)?;
    let merged = cluster.dir.join("merged2.exr");
    let o = merge(&beamlight, &out, total, &merged)?;
    let err = String::from_utf8_lossy(&o.stderr);
    let (a, b) = (CANCELLED * PER_TASK, (CANCELLED + 1) * PER_TASK);
    let expected = format!("passes {a}..{b} are missing");
    if o.status.success() || !err.contains(&expected) || !err.contains(&format!("{a}..{b}  MISSING")) {
        bail!(
            "merge of the incomplete set should fail naming '{expected}' (exit {}):\n{err}",
            o.status
        );
    }
    if merged.exists() {
        bail!("the refused merge left {} behind", merged.display());
    }
    println!(
        "merge refused the incomplete set (exit {}), as it should:",
        o.status.code().unwrap_or(-1)
    );
    print!("{}", indent(&err));
    let id = job.submit(&CANCELLED.to_string(), &out, false)?;
    cluster.wait(&id)?;
    cluster.expect_states(&id, &[(CANCELLED, Some("COMPLETED"))], &out)?;
    let o = merge(&beamlight, &out, total, &merged)?;
    if !o.status.success() {
        bail!(
            "merge after resubmitting task {CANCELLED} failed:\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    print!("{}", indent(&String::from_utf8_lossy(&o.stderr)));
    println!("{}", same_bits(&merged, &whole)?);
    let s2 = t2.elapsed();

    cluster.passed = true;
    drop(cluster);
    println!(
        "\n{:.1} s after the build, teardown included (cluster up in {:.1} s, scenario 1 {:.1} s, scenario 2 {:.1} s)",
        t0.elapsed().as_secs_f64(),
        up.as_secs_f64(),
        s1.as_secs_f64(),
        s2.as_secs_f64()
    );
    // Both scenarios, in the plain form test-result readers take.
    println!("cluster: 2 passed, 0 failed");
    Ok(())
}

/// The job script: the fenced block between the README's `slurm-job-array` markers.
pub fn job_script(readme: &str) -> Result<String> {
    let start = readme
        .find(BEGIN)
        .context("README.md has no `<!-- slurm-job-array:begin -->` marker")?;
    let end = readme[start..]
        .find(END)
        .map(|e| start + e)
        .context("README.md has no `<!-- slurm-job-array:end -->` marker after the begin marker")?;
    let block: Vec<&str> = readme[start..end].lines().skip(1).collect();
    let (Some(first), Some(last)) = (block.first(), block.iter().rposition(|l| !l.trim().is_empty())) else {
        bail!("README.md: nothing between the slurm-job-array markers");
    };
    if !first.starts_with("```") || block[last].trim() != "```" {
        bail!("README.md: the slurm-job-array markers must enclose one fenced code block");
    }
    let script: String = block[1..last].iter().map(|l| format!("{l}\n")).collect();
    if !script.starts_with("#!") {
        bail!("README.md: the slurm job script must start with a #! line");
    }
    Ok(script)
}

/// Installs `slurm-wlm` and `munge` with apt-get when a program of theirs is missing.
fn ensure_installed() -> Result<()> {
    let programs = [
        "munged",
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "scancel",
        "scontrol",
        "sinfo",
    ];
    let missing: Vec<&str> = programs.into_iter().filter(|p| which(p).is_none()).collect();
    if missing.is_empty() {
        return Ok(());
    }
    eprintln!(
        "Slurm not found ({} missing); installing slurm-wlm and munge with apt-get",
        missing.join(", ")
    );
    let apt = |args: &[&str]| {
        let mut c = Command::new("apt-get");
        c.args(args).env("DEBIAN_FRONTEND", "noninteractive");
        c
    };
    let install = super::run(&mut apt(&["update"])).and_then(|()| {
        super::run(&mut apt(&[
            "install",
            "-y",
            "--no-install-recommends",
            "slurm-wlm",
            "munge",
        ]))
    });
    install.context("installing Slurm (Debian's slurm-wlm and munge) with apt-get failed; install them by hand to run `cargo xtask cluster`")?;
    let still: Vec<&str> = programs.into_iter().filter(|p| which(p).is_none()).collect();
    if !still.is_empty() {
        bail!(
            "slurm-wlm and munge are installed, but {} still cannot be found on the PATH or in /usr/sbin",
            still.join(", ")
        );
    }
    Ok(())
}

/// The program's path: on the PATH, or in /usr/sbin (where the daemons are).
fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/usr/bin")])
        .map(|d| d.join(program))
        .find(|p| p.is_file())
}

/// `cargo build --release -p beamlight` (CARGO_BUILD_JOBS limits its jobs); the binary's path.
fn build_beamlight(root: &Path) -> Result<PathBuf> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    super::run(
        Command::new(cargo)
            .current_dir(root)
            .args(["build", "--release", "-p", "beamlight"]),
    )?;
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from);
    let bin = target.join("release/beamlight");
    if !bin.is_file() {
        bail!("{} was not built", bin.display());
    }
    Ok(bin)
}

/// Runs a command, failing with its output when it fails.
fn run_quiet(cmd: &mut Command) -> Result<Output> {
    let o = cmd.output().with_context(|| format!("running {cmd:?}"))?;
    if !o.status.success() {
        bail!(
            "{cmd:?} failed ({}):\n{}{}",
            o.status,
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    Ok(o)
}

fn indent(text: &str) -> String {
    text.lines().map(|l| format!("  | {l}\n")).collect()
}

/// `beamlight merge OUT/*.accum --passes 0..TOTAL -o MERGED`, echoed; its output, whatever it is.
fn merge(beamlight: &Path, parts_dir: &Path, total: u64, merged: &Path) -> Result<Output> {
    let mut parts: Vec<PathBuf> = std::fs::read_dir(parts_dir)
        .with_context(|| format!("reading {}", parts_dir.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    parts.retain(|p| p.extension().is_some_and(|e| e == "accum"));
    parts.sort();
    println!(
        "+ beamlight merge {}/part-*.accum --passes 0..{total} -o {}",
        parts_dir.display(),
        merged.display()
    );
    Command::new(beamlight)
        .arg("merge")
        .args(&parts)
        .args(["--passes", &format!("0..{total}"), "-o"])
        .arg(merged)
        .output()
        .context("running beamlight merge")
}

/// Every layer of two EXRs, pixel for pixel, bit for bit; a line saying what was compared.
fn same_bits(a: &Path, b: &Path) -> Result<String> {
    let read =
        |p: &Path| beamlight_render::output::read_exr_layers(p).with_context(|| format!("reading {}", p.display()));
    let (la, lb) = (read(a)?, read(b)?);
    let names = |l: &[(String, beamlight_render::Image)]| l.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    if names(&la) != names(&lb) {
        bail!(
            "{} has layers {:?}, {} has {:?}",
            a.display(),
            names(&la),
            b.display(),
            names(&lb)
        );
    }
    let mut values = 0usize;
    for ((name, ia), (_, ib)) in la.iter().zip(&lb) {
        if (ia.width, ia.height) != (ib.width, ib.height) {
            bail!(
                "layer {name}: {}×{} against {}×{}",
                ia.width,
                ia.height,
                ib.width,
                ib.height
            );
        }
        for (i, (p, q)) in ia.pixels.iter().zip(&ib.pixels).enumerate() {
            for c in 0..3 {
                if p[c].to_bits() != q[c].to_bits() {
                    bail!(
                        "{} differs from {}: layer {name}, pixel ({}, {}), channel {c}: {:e} against {:e}",
                        a.display(),
                        b.display(),
                        i as u32 % ia.width,
                        i as u32 / ia.width,
                        p[c],
                        q[c]
                    );
                }
                values += 1;
            }
        }
    }
    let (w, h) = la.first().map_or((0, 0), |(_, i)| (i.width, i.height));
    Ok(format!(
        "{} = {} bit for bit: {} layers ({}) of {w}×{h}, {values} values",
        a.file_name().unwrap_or_default().to_string_lossy(),
        b.file_name().unwrap_or_default().to_string_lossy(),
        la.len(),
        names(&la).join(", ")
    ))
}

/// Submissions of the README's job script with this run's settings.
struct Job<'a> {
    cluster: &'a Cluster,
    script: &'a Path,
    beamlight: &'a Path,
    scene: &'a Path,
}

impl Job<'_> {
    /// `sbatch --array=ARRAY` of the script with its settings in the environment (held with
    /// `hold`); the job id.
    fn submit(&self, array: &str, out: &Path, hold: bool) -> Result<String> {
        let c = self.cluster;
        let mut cmd = c.cmd("sbatch");
        cmd.args(["--parsable", &format!("--array={array}")])
            .arg(format!("--output={}/slurm-%A_%a.out", c.dir.join("logs").display()))
            .arg(format!("--chdir={}", c.dir.display()));
        if hold {
            cmd.arg("--hold");
        }
        cmd.arg(self.script)
            .env("SCENE", self.scene)
            .env("PER_TASK", PER_TASK.to_string())
            .env("OUT", out)
            .env("RENDER_ARGS", RENDER_ARGS)
            .env("BEAMLIGHT", self.beamlight);
        let o = run_quiet(&mut cmd)?;
        let id = String::from_utf8_lossy(&o.stdout)
            .trim()
            .split(';')
            .next()
            .unwrap_or_default()
            .to_string();
        if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
            bail!("sbatch printed no job id: {:?}", String::from_utf8_lossy(&o.stdout));
        }
        println!(
            "+ SCENE={} PER_TASK={PER_TASK} OUT={} RENDER_ARGS=\"{RENDER_ARGS}\" BEAMLIGHT={} sbatch --array={array}{} render_array.sh  -> job {id}",
            self.scene.display(),
            out.display(),
            self.beamlight.display(),
            if hold { " --hold" } else { "" }
        );
        Ok(id)
    }
}

struct Daemon {
    name: &'static str,
    child: Child,
    log: PathBuf,
}

/// A one-node Slurm cluster in a temporary directory; dropping it tears it down.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    daemons: Vec<Daemon>,
    /// Keep the directory even when the run passes (`--keep`); a failed run always keeps it.
    keep: bool,
    passed: bool,
}

impl Cluster {
    fn start(keep: bool) -> Result<Cluster> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir = std::env::temp_dir().join(format!("beamlight-slurm-{}-{nanos}", std::process::id()));
        for sub in ["munge", "state", "spool", "log", "logs"] {
            std::fs::create_dir_all(dir.join(sub)).with_context(|| format!("creating {}", dir.join(sub).display()))?;
        }
        let mut cluster = Cluster {
            conf: dir.join("slurm.conf"),
            dir,
            daemons: Vec::new(),
            keep,
            passed: false,
        };
        println!("cluster: directory {}", cluster.dir.display());
        cluster.start_munge()?;
        cluster.write_conf()?;
        cluster.start_slurm()?;
        Ok(cluster)
    }

    fn start_munge(&mut self) -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let munge = self.dir.join("munge");
        let mut key = vec![0u8; 1024];
        std::io::Read::read_exact(&mut std::fs::File::open("/dev/urandom")?, &mut key)?;
        let key_file = munge.join("munge.key");
        std::fs::write(&key_file, &key)?;
        std::fs::set_permissions(&key_file, std::fs::Permissions::from_mode(0o400))?;
        std::fs::set_permissions(&munge, std::fs::Permissions::from_mode(0o711))?;
        let socket = munge.join("munge.socket");
        let mut cmd = Command::new(which("munged").context("munged not found")?);
        // --force: the socket lives in a world-writable /tmp (sticky, but munged still asks).
        cmd.args(["--foreground", "--force"])
            .arg(format!("--key-file={}", key_file.display()))
            .arg(format!("--socket={}", socket.display()))
            .arg(format!("--pid-file={}", munge.join("munged.pid").display()))
            .arg(format!("--seed-file={}", munge.join("munged.seed").display()))
            .arg(format!("--log-file={}", self.dir.join("log/munged.log").display()));
        self.spawn("munged", cmd)?;
        self.wait_until("munged", Duration::from_secs(15), |_| {
            Ok(socket
                .exists()
                .then_some(())
                .ok_or(format!("no socket {}", socket.display())))
        })
    }

    fn write_conf(&self) -> Result<()> {
        let d = self.dir.display();
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let mem_mb = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|m| {
                m.lines()
                    .find_map(|l| l.strip_prefix("MemTotal:"))
                    .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            })
            .map_or(1024, |kb| kb / 1024);
        let (ctld_port, slurmd_port) = (free_port()?, free_port()?);
        let conf = format!(
            "# Generated by `cargo xtask cluster`: one node on this machine, everything under {d}.
ClusterName=beamlight
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort={ctld_port}
SlurmdPort={slurmd_port}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={d}/munge/munge.socket
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups: processes tracked by parentage, tasks not confined.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
# The node's size is the configured one, whatever slurmd detects.
SlurmdParameters=config_overrides
# Finished jobs stay visible to scontrol for 10 minutes (there is no accounting database).
MinJobAge=600
KillWait=5
NodeName={NODE} NodeHostname=localhost NodeAddr=127.0.0.1 CPUs={cpus} RealMemory={mem_mb} State=UNKNOWN
PartitionName=main Nodes={NODE} Default=YES MaxTime=INFINITE State=UP
"
        );
        std::fs::write(&self.conf, conf).with_context(|| format!("writing {}", self.conf.display()))?;
        println!(
            "cluster: slurm.conf with node {NODE} ({cpus} CPUs, {mem_mb} MB), slurmctld on port {ctld_port}, slurmd on {slurmd_port}"
        );
        Ok(())
    }

    fn start_slurm(&mut self) -> Result<()> {
        let mut ctld = Command::new(which("slurmctld").context("slurmctld not found")?);
        ctld.args(["-D", "-c", "-f"]).arg(&self.conf);
        self.spawn("slurmctld", ctld)?;
        self.wait_until("slurmctld", Duration::from_secs(30), |c| {
            let o = c.cmd("scontrol").arg("ping").output()?;
            let said = String::from_utf8_lossy(&o.stdout).trim().to_string();
            Ok((o.status.success() && said.contains("is UP"))
                .then_some(())
                .ok_or(format!("`scontrol ping` says '{said}'")))
        })?;
        let mut slurmd = Command::new(which("slurmd").context("slurmd not found")?);
        slurmd.args(["-D", "-f"]).arg(&self.conf).args(["-N", NODE]);
        self.spawn("slurmd", slurmd)?;
        self.wait_until("slurmd", Duration::from_secs(60), |c| {
            let o = c.cmd("sinfo").args(["-h", "-N", "-n", NODE, "-o", "%T"]).output()?;
            let state = String::from_utf8_lossy(&o.stdout).trim().to_string();
            Ok((state == "idle")
                .then_some(())
                .ok_or(format!("node {NODE} is '{state}' in sinfo, not idle")))
        })?;
        let o = run_quiet(self.cmd("sinfo").args(["-N", "-o", "%N %P %T %c %m"]))?;
        print!("cluster: up\n{}", indent(&String::from_utf8_lossy(&o.stdout)));
        Ok(())
    }

    /// Starts a daemon in the foreground, its output going to `log/NAME.log`.
    fn spawn(&mut self, name: &'static str, mut cmd: Command) -> Result<()> {
        let log = self.dir.join("log").join(format!("{name}.log"));
        let out = std::fs::OpenOptions::new().create(true).append(true).open(&log)?;
        cmd.stdin(Stdio::null())
            .stdout(out.try_clone()?)
            .stderr(out)
            .env("SLURM_CONF", &self.conf);
        let child = cmd.spawn().with_context(|| format!("starting {name} ({cmd:?})"))?;
        println!("cluster: started {name} (pid {})", child.id());
        self.daemons.push(Daemon { name, child, log });
        Ok(())
    }

    /// Polls `ready` (`Err(what is not ready yet)`) until it is; fails with the tail of the
    /// daemon's log when the daemon exits or `limit` passes.
    fn wait_until(
        &mut self,
        name: &str,
        limit: Duration,
        mut ready: impl FnMut(&Cluster) -> Result<std::result::Result<(), String>>,
    ) -> Result<()> {
        let start = Instant::now();
        loop {
            let d = self.daemons.iter_mut().find(|d| d.name == name).expect("started");
            if let Some(status) = d.child.try_wait()? {
                let log = d.log.clone();
                bail!(
                    "{name} did not start: it exited ({status}); the end of {}:\n{}",
                    log.display(),
                    tail(&log, 25)
                );
            }
            let not_yet = match ready(self)? {
                Ok(()) => return Ok(()),
                Err(why) => why,
            };
            if start.elapsed() > limit {
                let log = self
                    .daemons
                    .iter()
                    .find(|d| d.name == name)
                    .expect("started")
                    .log
                    .clone();
                bail!(
                    "{name} did not come up within {} s ({not_yet}); the end of {}:\n{}",
                    limit.as_secs(),
                    log.display(),
                    tail(&log, 25)
                );
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// A Slurm client command talking to this cluster.
    fn cmd(&self, program: &str) -> Command {
        let mut c = Command::new(which(program).unwrap_or_else(|| program.into()));
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn run(&self, cmd: &mut Command) -> Result<()> {
        let args: Vec<String> = cmd.get_args().map(|a| a.to_string_lossy().into_owned()).collect();
        println!(
            "+ {} {}",
            cmd.get_program().to_string_lossy().rsplit('/').next().unwrap_or(""),
            args.join(" ")
        );
        run_quiet(cmd).map(|_| ())
    }

    /// Waits until no task of the job is pending or running.
    fn wait(&self, job: &str) -> Result<()> {
        let start = Instant::now();
        loop {
            let o = run_quiet(self.cmd("squeue").args(["-h", "-j", job, "-o", "%i %T"]))?;
            let queued = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if queued.is_empty() {
                println!("job {job}: finished after {:.1} s", start.elapsed().as_secs_f64());
                return Ok(());
            }
            if start.elapsed() > Duration::from_secs(600) {
                bail!(
                    "job {job} still queued after 10 minutes:\n{queued}\nthe end of the slurmctld log:\n{}",
                    tail(&self.dir.join("log/slurmctld.log"), 15)
                );
            }
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    /// The array task ids of a job that Slurm knows of, in any state (`squeue -t all`).
    fn tasks(&self, job: &str) -> Result<Vec<u64>> {
        let o = run_quiet(
            self.cmd("squeue")
                .args(["-h", "-r", "-t", "all", "-j", job, "-o", "%K"]),
        )?;
        let mut ids: Vec<u64> = String::from_utf8_lossy(&o.stdout)
            .split_whitespace()
            .map(|t| t.parse().with_context(|| format!("squeue printed task id '{t}'")))
            .collect::<Result<_>>()?;
        ids.sort();
        Ok(ids)
    }

    /// Checks each array task's final state (`scontrol show job`; `None`: no record, as for a
    /// task cancelled before it started), printing them; a task in another state fails the run
    /// with its output.
    fn expect_states(&self, job: &str, expected: &[(u64, Option<&str>)], out: &Path) -> Result<()> {
        let o = run_quiet(self.cmd("scontrol").args(["show", "job", "-o", job]))?;
        let text = String::from_utf8_lossy(&o.stdout);
        let field = |line: &str, key: &str| {
            line.split_whitespace()
                .find_map(|f| f.strip_prefix(key).map(str::to_string))
                .unwrap_or_default()
        };
        let tasks: Vec<(u64, String, String)> = text
            .lines()
            .filter_map(|l| {
                let task = field(l, "ArrayTaskId=").parse().ok()?;
                Some((task, field(l, "JobState="), field(l, "RunTime=")))
            })
            .collect();
        let mut bad = Vec::new();
        for &(task, want) in expected {
            let (first, end) = (task * PER_TASK, (task + 1) * PER_TASK);
            let found = tasks.iter().find(|(t, ..)| *t == task);
            match (found, want) {
                (Some((_, state, runtime)), _) => {
                    println!("  task {job}_{task} (passes {first}..{end}): {state}, run time {runtime}");
                    if Some(state.as_str()) != want {
                        bad.push(format!(
                            "task {task}: {state}, expected {}; its output ({}):\n{}",
                            want.unwrap_or("no record"),
                            self.task_log(job, task).display(),
                            tail(&self.task_log(job, task), 20)
                        ));
                    }
                }
                (None, None) => println!("  task {job}_{task} (passes {first}..{end}): cancelled, never ran"),
                (None, Some(want)) => bad.push(format!("task {task}: not shown by scontrol, expected {want}:\n{text}")),
            }
        }
        if !bad.is_empty() {
            bail!("job {job} ({}):\n{}", out.display(), bad.join("\n"));
        }
        Ok(())
    }

    fn task_log(&self, job: &str, task: u64) -> PathBuf {
        self.dir.join(format!("logs/slurm-{job}_{task}.out"))
    }
}

impl Drop for Cluster {
    /// Cancels every job, stops the daemons (TERM, then KILL after 10 s) and removes the
    /// directory after a run that passed, unless `--keep`.
    fn drop(&mut self) {
        if self.daemons.iter().any(|d| d.name == "slurmctld") {
            let jobs = self
                .cmd("squeue")
                .args(["-h", "-o", "%A"])
                .output()
                .map(|o| {
                    String::from_utf8_lossy(&o.stdout)
                        .split_whitespace()
                        .map(str::to_string)
                        .collect::<Vec<_>>()
                })
                .unwrap_or_default();
            if !jobs.is_empty() {
                let _ = self.cmd("scancel").args(&jobs).status();
                let start = Instant::now();
                while start.elapsed() < Duration::from_secs(15)
                    && self
                        .cmd("squeue")
                        .args(["-h", "-o", "%A"])
                        .output()
                        .is_ok_and(|o| !o.stdout.trim_ascii().is_empty())
                {
                    std::thread::sleep(Duration::from_millis(250));
                }
            }
        }
        let mut stopped = Vec::new();
        for d in self.daemons.iter_mut().rev() {
            if matches!(d.child.try_wait(), Ok(None)) {
                let _ = Command::new("kill").args(["-TERM", &d.child.id().to_string()]).status();
                let start = Instant::now();
                while matches!(d.child.try_wait(), Ok(None)) && start.elapsed() < Duration::from_secs(10) {
                    std::thread::sleep(Duration::from_millis(100));
                }
                let _ = d.child.kill();
            }
            let _ = d.child.wait();
            stopped.push(d.name);
        }
        if self.keep || !self.passed {
            println!(
                "cluster: stopped {}; kept {} (logs in log/ and logs/)",
                stopped.join(", "),
                self.dir.display()
            );
        } else {
            let _ = std::fs::remove_dir_all(&self.dir);
            println!(
                "cluster: stopped {}; removed {}",
                stopped.join(", "),
                self.dir.display()
            );
        }
    }
}

/// A TCP port that nothing listens on now.
fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// The last `n` lines of a file (or why there are none).
fn tail(path: &Path, n: usize) -> String {
    match std::fs::read_to_string(path) {
        Ok(text) if text.trim().is_empty() => "  (empty)".into(),
        Ok(text) => {
            let lines: Vec<&str> = text.lines().collect();
            lines[lines.len().saturating_sub(n)..]
                .iter()
                .map(|l| format!("  {l}\n"))
                .collect()
        }
        Err(e) => format!("  (cannot read it: {e})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The README holds the job script between its markers, and it is valid bash using the
    /// settings `cargo xtask cluster` passes in the environment.
    #[test]
    fn readme_job_script_is_extracted_and_parses() {
        let readme = std::fs::read_to_string(crate::root().join("README.md")).unwrap();
        let script = job_script(&readme).unwrap();
        assert!(script.starts_with("#!/bin/bash\n"), "{script}");
        for var in [
            "$SCENE",
            "PER_TASK",
            "$OUT",
            "RENDER_ARGS",
            "BEAMLIGHT",
            "SLURM_ARRAY_TASK_ID",
            "--passes",
        ] {
            assert!(script.contains(var), "the job script does not use {var}:\n{script}");
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("render_array.sh");
        std::fs::write(&path, &script).unwrap();
        let o = Command::new("bash").arg("-n").arg(&path).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // Run outside Slurm with a stand-in binary, it renders its task's range.
        let fake = dir.path().join("fake-beamlight");
        std::fs::write(&fake, "#!/bin/sh\necho \"$@\"\n").unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
        let o = Command::new("bash")
            .arg(&path)
            .env("SLURM_ARRAY_TASK_ID", "3")
            .env("PER_TASK", "5")
            .env("SCENE", "s.toml")
            .env("OUT", dir.path().join("parts"))
            .env("RENDER_ARGS", "--method pt --width 8")
            .env("BEAMLIGHT", &fake)
            .env_remove("SLURM_CPUS_PER_TASK")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            String::from_utf8_lossy(&o.stdout).trim(),
            format!(
                "render s.toml -o {}/part-3.exr --passes 15..20 --threads 1 --method pt --width 8",
                dir.path().join("parts").display()
            )
        );
    }

    #[test]
    fn job_script_markers_are_required() {
        assert!(job_script("no markers").is_err());
        let ok = "x\n<!-- slurm-job-array:begin -->\n```sh\n#!/bin/bash\necho hi\n```\n<!-- slurm-job-array:end -->\n";
        assert_eq!(job_script(ok).unwrap(), "#!/bin/bash\necho hi\n");
        assert!(job_script(&ok.replace("```sh\n", "")).is_err());
    }
}

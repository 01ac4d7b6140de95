//! `lightgrid bake world.toml`: a whole world's light grids as Bevy volumes, baked as a
//! graph of tasks (issue 49).
//!
//! The graph: the world grid; every node grid of every depth (its boundary read from the
//! coarser grids that cover it: `lightgrid_terrain_lod::bake`); one Bevy volume per node;
//! the manifest, which puts the volumes and `<name>.manifest.json` into the output
//! folder. Every task but the manifest writes into a **store** (a folder, local or
//! shared), under `objects/<hash>/`, where `<hash>` is the content hash of the task's
//! inputs: the scene's light-relevant content and files
//! (`SceneFile::light_hash`), the task's own settings and its inputs' hashes. A task
//! whose folder exists is not run again (a retried, repeated or re-baked task writes the
//! same bytes), so a re-bake after a change runs only the tasks whose inputs changed. A
//! task writes into a temporary folder beside and renames it into place: a task killed
//! half way leaves no output, and its retry removes what it left.
//!
//! `--plan FILE` writes the graph as JSON (ids, hashes, dependencies, points and memory
//! per task, the command that runs each), `--task ID` runs one task (its inputs must be
//! in the store), and with neither the whole graph runs here, task after task, in the
//! plan's order. A distributed driver (`python/lightgrid_ray`) runs the same commands.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use lightgrid_core::glam::{IVec2, Vec3};
use lightgrid_core::hash::ContentHash;
use lightgrid_export::{BevyVolume, Content, TexelFormat, write_volumes};
use lightgrid_terrain_lod::NodeKey;
use lightgrid_terrain_lod::bake::{
    BAKE_BYTES_PER_POINT, BakedGrid, READ_BYTES_PER_POINT, WorldBake,
};
use lightgrid_viewer::SceneFile;
use serde::Serialize;

/// Environment variable that kills a task half way, once, for tests of retries:
/// `<task id>@<marker file>`; the task writes part of its output, creates the marker and
/// aborts; with the marker present it runs normally.
pub(crate) const FAULT_ENV: &str = "LIGHTGRID_BAKE_FAULT";

/// Memory a task's process holds besides its grids (the composer's model grids, the
/// program): a guess for the plan's requests.
const BASE_BYTES: u64 = 256 << 20;

/// How a world is baked (from the command line).
pub(crate) struct WorldArgs {
    pub scene: PathBuf,
    pub output: PathBuf,
    pub name: String,
    pub store: Option<PathBuf>,
    pub format: TexelFormat,
    pub unit_scale: f32,
    pub depths: Option<u32>,
    pub plan: Option<PathBuf>,
    pub task: Option<String>,
}

/// What a task does.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    World,
    Node(NodeKey),
    Export(NodeKey),
    Manifest,
}

/// One task of the graph.
#[derive(Debug, Clone)]
struct Task {
    id: String,
    kind: Kind,
    hash: u64,
    /// Indices of the tasks whose outputs it reads.
    deps: Vec<usize>,
    points: u64,
    memory: u64,
}

/// A task as the plan file lists it.
#[derive(Serialize)]
struct PlannedTask<'a> {
    id: &'a str,
    kind: &'static str,
    hash: String,
    deps: Vec<&'a str>,
    points: u64,
    memory_bytes: u64,
    argv: Vec<String>,
}

/// The plan file.
#[derive(Serialize)]
struct PlanFile<'a> {
    version: u32,
    scene: String,
    store: String,
    output: String,
    tasks: Vec<PlannedTask<'a>>,
}

/// What running a task did (printed as a JSON line by `--task`).
#[derive(Serialize)]
struct Outcome {
    task: String,
    hash: String,
    ran: bool,
    seconds: f64,
}

/// Everything a task needs.
struct Ctx {
    args: WorldArgs,
    store: PathBuf,
    bake: WorldBake,
    sun: (Vec3, Vec3),
    split: bool,
    tasks: Vec<Task>,
    /// Grids kept in memory between the tasks of one process (by task), while tasks
    /// still to run read them and within [`CACHE_BYTES`]; the store holds them all.
    cache: HashMap<usize, Arc<BakedGrid>>,
    cached_bytes: u64,
    /// The world grid's tiles, when the world task ran in this process.
    tiles: HashMap<IVec2, Arc<BakedGrid>>,
    /// Tasks still to run that read each task's output.
    readers: Vec<usize>,
}

/// Most bytes of grids a process keeps in memory between tasks.
const CACHE_BYTES: u64 = 1 << 30;

fn hex(h: u64) -> String {
    format!("{h:016x}")
}

fn node_id(prefix: &str, k: NodeKey) -> String {
    format!("{prefix}-{}-{}-{}", k.depth, k.index.x, k.index.y)
}

/// Runs `lightgrid bake world.toml ...`.
pub(crate) fn run(args: WorldArgs) -> Result<()> {
    let ctx = Ctx::new(args)?;
    if let Some(plan) = ctx.args.plan.clone() {
        return ctx.write_plan(&plan);
    }
    if let Some(id) = ctx.args.task.clone() {
        let i = ctx
            .tasks
            .iter()
            .position(|t| t.id == id)
            .with_context(|| format!("--task {id}: no such task in this world's plan"))?;
        let mut ctx = ctx;
        let o = ctx.run_task(i)?;
        println!("{}", serde_json::to_string(&o)?);
        return Ok(());
    }
    ctx.run_all()
}

impl Ctx {
    fn new(args: WorldArgs) -> Result<Self> {
        let t = Instant::now();
        let scene = SceneFile::load(&args.scene)?;
        let scene_hash = scene.light_hash()?;
        let (bake, sun) = lightgrid_viewer::world::world_bake(&scene)?;
        let depths = args.depths.unwrap_or(u32::MAX);
        if depths == 0 {
            bail!(
                "--depths = 0: must be at least 1 (the world grid alone has no volumes to export)"
            );
        }
        let planned = bake.plan(depths)?;
        let store = match &args.store {
            Some(s) => s.clone(),
            None => args.output.join(".lightgrid-store"),
        };
        let mut ctx = Self {
            store,
            bake,
            sun,
            split: scene.sun.split,
            tasks: Vec::new(),
            args,
            cache: HashMap::new(),
            cached_bytes: 0,
            tiles: HashMap::new(),
            readers: Vec::new(),
        };
        ctx.tasks = ctx.graph(scene_hash, &planned);
        ctx.readers = vec![0; ctx.tasks.len()];
        for t in &ctx.tasks {
            for &d in &t.deps {
                ctx.readers[d] += 1;
            }
        }
        tracing::info!(
            tasks = ctx.tasks.len(),
            seconds = t.elapsed().as_secs_f64(),
            "world laid out"
        );
        Ok(ctx)
    }

    /// The task graph, in an order that runs every task after its inputs.
    fn graph(
        &self,
        scene_hash: u64,
        planned: &[lightgrid_terrain_lod::bake::PlannedNode],
    ) -> Vec<Task> {
        let world_points = self.bake.world_points();
        let mut tasks = vec![Task {
            id: "world".into(),
            kind: Kind::World,
            hash: ContentHash::new(b"lightgrid-bake-world-v1")
                .u64(scene_hash)
                .finish(),
            deps: vec![],
            points: world_points,
            memory: BASE_BYTES + world_points * BAKE_BYTES_PER_POINT,
        }];
        let mut index: HashMap<NodeKey, usize> = HashMap::new();
        for p in planned {
            let mut h = ContentHash::new(b"lightgrid-bake-node-v1");
            h.u64(scene_hash)
                .u32(p.key.depth)
                .u32(p.key.index.x as u32)
                .u32(p.key.index.y as u32)
                .u64(tasks[0].hash);
            let mut deps = vec![0];
            let mut read_points = self.bake.tile_points_bound();
            for r in &p.reads {
                let i = index[r];
                h.u64(tasks[i].hash);
                deps.push(i);
                read_points += tasks[i].points;
            }
            index.insert(p.key, tasks.len());
            tasks.push(Task {
                id: node_id("node", p.key),
                kind: Kind::Node(p.key),
                hash: h.finish(),
                deps,
                points: p.max_points,
                memory: BASE_BYTES
                    + p.max_points * BAKE_BYTES_PER_POINT
                    + read_points * READ_BYTES_PER_POINT,
            });
        }
        let (format, scale) = (self.args.format as u32, self.args.unit_scale);
        let mut manifest = ContentHash::new(b"lightgrid-bake-manifest-v1");
        manifest.bytes(self.args.name.as_bytes());
        let mut exports = Vec::new();
        for p in planned {
            let n = index[&p.key];
            let hash = ContentHash::new(b"lightgrid-bake-export-v1")
                .u64(tasks[n].hash)
                .u32(format)
                .f32s(&[scale])
                .finish();
            manifest.u64(hash);
            exports.push(tasks.len());
            tasks.push(Task {
                id: node_id("export", p.key),
                kind: Kind::Export(p.key),
                hash,
                deps: vec![n],
                points: p.max_points,
                memory: BASE_BYTES + p.max_points * (READ_BYTES_PER_POINT + 64),
            });
        }
        tasks.push(Task {
            id: "manifest".into(),
            kind: Kind::Manifest,
            hash: manifest.finish(),
            deps: exports,
            points: 0,
            memory: BASE_BYTES,
        });
        tasks
    }

    /// The command line that runs task `id`.
    fn argv(&self, id: &str) -> Vec<String> {
        let a = &self.args;
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let mut v = vec![
            "bake".to_string(),
            abs(&a.scene).display().to_string(),
            "--output".into(),
            abs(&a.output).display().to_string(),
            "--store".into(),
            abs(&self.store).display().to_string(),
            "--name".into(),
            a.name.clone(),
            "--format".into(),
            match a.format {
                TexelFormat::Rg11b10 => "rg11b10".into(),
                _ => "rgb9e5".into(),
            },
            "--unit-scale".into(),
            a.unit_scale.to_string(),
        ];
        if let Some(d) = a.depths {
            v.extend(["--depths".into(), d.to_string()]);
        }
        v.extend(["--task".into(), id.to_string()]);
        v
    }

    fn write_plan(&self, path: &Path) -> Result<()> {
        let abs = |p: &Path| {
            std::path::absolute(p)
                .unwrap_or_else(|_| p.to_path_buf())
                .display()
                .to_string()
        };
        let plan = PlanFile {
            version: 1,
            scene: abs(&self.args.scene),
            store: abs(&self.store),
            output: abs(&self.args.output),
            tasks: self
                .tasks
                .iter()
                .map(|t| PlannedTask {
                    id: &t.id,
                    kind: match t.kind {
                        Kind::World => "world",
                        Kind::Node(_) => "node",
                        Kind::Export(_) => "export",
                        Kind::Manifest => "manifest",
                    },
                    hash: hex(t.hash),
                    deps: t.deps.iter().map(|&d| self.tasks[d].id.as_str()).collect(),
                    points: t.points,
                    memory_bytes: t.memory,
                    argv: self.argv(&t.id),
                })
                .collect(),
        };
        let json = serde_json::to_string_pretty(&plan)?;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        lightgrid_core::file::write_atomic(path, json.as_bytes())
            .with_context(|| format!("writing the plan {}", path.display()))?;
        let points: u64 = self.tasks.iter().map(|t| t.points).sum();
        println!(
            "plan: {} tasks ({} grids, {} points at most) -> {}",
            self.tasks.len(),
            self.tasks
                .iter()
                .filter(|t| matches!(t.kind, Kind::World | Kind::Node(_)))
                .count(),
            points,
            path.display()
        );
        Ok(())
    }

    /// Every task here, in the plan's order.
    fn run_all(mut self) -> Result<()> {
        let t = Instant::now();
        let pb = indicatif::ProgressBar::new(self.tasks.len() as u64);
        if std::env::var_os("LIGHTGRID_QUIET").is_some() {
            pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        pb.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} tasks {msg}")
                .expect("valid template"),
        );
        // The plan's order, but each node's export right after the node, while its grid
        // is in memory (the results do not depend on the order).
        let mut export_of = vec![None; self.tasks.len()];
        for (e, t) in self.tasks.iter().enumerate() {
            if let Kind::Export(_) = t.kind {
                export_of[t.deps[0]] = Some(e);
            }
        }
        let mut order = Vec::with_capacity(self.tasks.len());
        for (i, t) in self.tasks.iter().enumerate() {
            match t.kind {
                Kind::Export(_) => {}
                Kind::Node(_) => order.extend(std::iter::once(i).chain(export_of[i])),
                _ => order.push(i),
            }
        }
        let mut ran = 0;
        for i in order {
            pb.set_message(self.tasks[i].id.clone());
            ran += self.run_task(i)?.ran as usize;
            pb.inc(1);
        }
        pb.finish_and_clear();
        println!(
            "baked {} tasks in {:.2} s: {ran} ran, {} found in the store {}",
            self.tasks.len(),
            t.elapsed().as_secs_f64(),
            self.tasks.len() - ran,
            self.store.display()
        );
        Ok(())
    }

    fn objects(&self) -> PathBuf {
        self.store.join("objects")
    }

    fn object(&self, i: usize) -> PathBuf {
        self.objects().join(hex(self.tasks[i].hash))
    }

    /// Runs task `i` unless its output is in the store.
    fn run_task(&mut self, i: usize) -> Result<Outcome> {
        let t = Instant::now();
        let task = self.tasks[i].clone();
        let _span = tracing::info_span!("task", id = %task.id).entered();
        let outcome = |ran| Outcome {
            task: task.id.clone(),
            hash: hex(task.hash),
            ran,
            seconds: t.elapsed().as_secs_f64(),
        };
        if task.kind == Kind::Manifest {
            self.manifest(&task)?;
            return Ok(outcome(true));
        }
        let done = self.object(i);
        if done.is_dir() {
            self.keep(i, None);
            return Ok(outcome(false));
        }
        let objects = self.objects();
        std::fs::create_dir_all(&objects)
            .with_context(|| format!("creating the store {}", objects.display()))?;
        // What an earlier attempt of this task left half written.
        let stale = format!(".tmp-{}-", hex(task.hash));
        for e in std::fs::read_dir(&objects)?.flatten() {
            if e.file_name().to_string_lossy().starts_with(&stale) {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
        let tmp = objects.join(format!("{stale}{}", std::process::id()));
        std::fs::create_dir_all(&tmp)?;
        let made = match task.kind {
            Kind::World => {
                let g = self.bake.world()?;
                // The tiles the nodes read (bounded in size however large the world).
                for (index, tile) in self.bake.world_tiles(&g)? {
                    let path = tmp.join(tile_name(index));
                    std::fs::write(&path, tile.to_bytes())
                        .with_context(|| format!("writing {}", path.display()))?;
                    if self.readers[i] > 0 {
                        self.tiles.insert(index, Arc::new(tile));
                    }
                }
                self.write_grid(&tmp, &task, &g)?;
                None
            }
            Kind::Node(key) => {
                let world = self.load_tile(key)?;
                let mut held = Vec::new();
                for &d in &task.deps[1..] {
                    if let Kind::Node(k) = self.tasks[d].kind {
                        held.push((k, self.load_grid(d)?));
                    }
                }
                let reads: Vec<(NodeKey, &BakedGrid)> =
                    held.iter().map(|(k, g)| (*k, g.as_ref())).collect();
                let g = self.bake.node(key, &world, &reads)?;
                self.write_grid(&tmp, &task, &g)?;
                Some(g)
            }
            Kind::Export(_) => {
                let g = self.load_grid(task.deps[0])?;
                self.export(&tmp, &task, &g)?;
                None
            }
            Kind::Manifest => unreachable!("handled above"),
        };
        if let Err(e) = std::fs::rename(&tmp, &done) {
            let _ = std::fs::remove_dir_all(&tmp);
            if !done.is_dir() {
                return Err(e).with_context(|| format!("moving {} into place", done.display()));
            }
        }
        self.keep(i, made);
        Ok(outcome(true))
    }

    /// After task `i`: its grid kept in memory for the tasks that will read it (within
    /// [`CACHE_BYTES`]), and the grids it read dropped once nothing left reads them.
    fn keep(&mut self, i: usize, made: Option<BakedGrid>) {
        let size = |g: &BakedGrid| g.light.desc().point_count() as u64 * READ_BYTES_PER_POINT;
        for d in self.tasks[i].deps.clone() {
            self.readers[d] = self.readers[d].saturating_sub(1);
            if self.readers[d] == 0
                && let Some(g) = self.cache.remove(&d)
            {
                self.cached_bytes -= size(&g);
            }
        }
        if let Some(g) = made
            && self.readers[i] > 0
            && self.cached_bytes + size(&g) <= CACHE_BYTES
        {
            self.cached_bytes += size(&g);
            self.cache.insert(i, Arc::new(g));
        }
    }

    /// A grid task's output, `grid.lgbake` in `tmp` (with the fault hook).
    fn write_grid(&self, tmp: &Path, task: &Task, g: &BakedGrid) -> Result<()> {
        let bytes = g.to_bytes();
        let path = tmp.join("grid.lgbake");
        fault_point(&task.id, &path, &bytes)?;
        std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))
    }

    /// The world grid's tile that node `key` reads (its depth-1 ancestor's).
    fn load_tile(&self, key: NodeKey) -> Result<Arc<BakedGrid>> {
        let index = key.index.div_euclid(IVec2::splat(1 << (key.depth - 1)));
        if let Some(t) = self.tiles.get(&index) {
            return Ok(t.clone());
        }
        let path = self.object(0).join(tile_name(index));
        let bytes = std::fs::read(&path).with_context(|| {
            format!(
                "reading {} (the output of task world: run it first)",
                path.display()
            )
        })?;
        let g =
            BakedGrid::from_bytes(&bytes).with_context(|| format!("reading {}", path.display()))?;
        Ok(Arc::new(g))
    }

    fn load_grid(&self, i: usize) -> Result<Arc<BakedGrid>> {
        if let Some(g) = self.cache.get(&i) {
            return Ok(g.clone());
        }
        let path = self.object(i).join("grid.lgbake");
        let bytes = std::fs::read(&path).with_context(|| {
            format!(
                "reading {} (the output of task {}: run it first)",
                path.display(),
                self.tasks[i].id
            )
        })?;
        let g =
            BakedGrid::from_bytes(&bytes).with_context(|| format!("reading {}", path.display()))?;
        Ok(Arc::new(g))
    }

    /// A node's Bevy volume: the sky's light plus the scattered sun (the direct sun is
    /// Bevy's `DirectionalLight`), or all light when the scene keeps the sun in the bins;
    /// points inside geometry take their valid neighbours' light.
    fn export(&self, tmp: &Path, task: &Task, g: &BakedGrid) -> Result<()> {
        let (field, content) = match &g.sun {
            Some(s) if self.split => {
                let data = g
                    .light
                    .data()
                    .iter()
                    .zip(s.scattered.data())
                    .map(|(a, b)| *a + *b * self.sun.1)
                    .collect();
                (
                    lightgrid_core::Grid::from_trusted(*g.light.desc(), data),
                    Content::Indirect,
                )
            }
            _ => (g.light.clone(), Content::All),
        };
        let valid = lightgrid_core::validity::valid_points(&g.material);
        let volume =
            BevyVolume::from_field_valid(&field, g.light.desc(), self.args.format, &valid)?;
        fault_point(&task.id, &tmp.join("volume.partial"), b"")?;
        // The node's box, for the manifest.
        let (lo, hi) = g.light.desc().point_bounds();
        let b: Vec<String> = lo
            .to_array()
            .iter()
            .chain(&hi.to_array())
            .map(|v| format!("{v:?}"))
            .collect();
        std::fs::write(tmp.join("box.txt"), b.join(" "))?;
        write_volumes(
            tmp,
            "volume",
            std::slice::from_ref(&volume),
            content,
            self.args.unit_scale,
            Some(self.sun),
        )?;
        Ok(())
    }

    /// The output folder: every node's volume as `<name>-<depth>-<x>-<z>.{dds,ktx2,json}`
    /// and `<name>.manifest.json`, written as one set.
    fn manifest(&self, task: &Task) -> Result<()> {
        #[derive(Serialize)]
        struct Volume {
            depth: u32,
            index: [i32; 2],
            hash: String,
            files: Vec<String>,
            min: [f32; 3],
            max: [f32; 3],
        }
        #[derive(Serialize)]
        struct Manifest {
            version: u32,
            hash: String,
            volumes: Vec<Volume>,
        }
        let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
        let mut volumes = Vec::new();
        for &e in &task.deps {
            let Kind::Export(key) = self.tasks[e].kind else {
                continue;
            };
            let from = self.object(e);
            let stem = format!(
                "{}-{}-{}-{}",
                self.args.name, key.depth, key.index.x, key.index.y
            );
            let mut names = Vec::new();
            for ext in ["dds", "ktx2", "json"] {
                let src = from.join(format!("volume.{ext}"));
                let bytes = std::fs::read(&src).with_context(|| {
                    format!(
                        "reading {} (run task {} first)",
                        src.display(),
                        self.tasks[e].id
                    )
                })?;
                let name = format!("{stem}.{ext}");
                files.push((self.args.output.join(&name), bytes));
                names.push(name);
            }
            let b = std::fs::read_to_string(from.join("box.txt"))?;
            let v: Vec<f32> = b
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .with_context(|| format!("reading {}", from.join("box.txt").display()))?;
            let [x0, y0, z0, x1, y1, z1] = v[..] else {
                bail!("{}: not six numbers", from.join("box.txt").display());
            };
            let (lo, hi) = (Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1));
            volumes.push(Volume {
                depth: key.depth,
                index: key.index.to_array(),
                hash: hex(self.tasks[e].hash),
                files: names,
                min: lo.to_array(),
                max: hi.to_array(),
            });
        }
        let m = Manifest {
            version: 1,
            hash: hex(task.hash),
            volumes,
        };
        files.push((
            self.args
                .output
                .join(format!("{}.manifest.json", self.args.name)),
            serde_json::to_string_pretty(&m)?.into_bytes(),
        ));
        std::fs::create_dir_all(&self.args.output)?;
        lightgrid_core::file::write_all_atomic(&files)
            .with_context(|| format!("writing into {}", self.args.output.display()))?;
        Ok(())
    }
}

/// The file of the world grid's tile for depth-1 node `index`.
fn tile_name(index: IVec2) -> String {
    format!("tile-{}-{}.lgbake", index.x, index.y)
}

/// The fault hook ([`FAULT_ENV`]): for task `id`, once, writes `bytes`' first half to
/// `path` and aborts the process.
fn fault_point(id: &str, path: &Path, bytes: &[u8]) -> Result<()> {
    let Ok(spec) = std::env::var(FAULT_ENV) else {
        return Ok(());
    };
    let Some((task, marker)) = spec.split_once('@') else {
        bail!("{FAULT_ENV} = {spec:?}: must be <task id>@<marker file>");
    };
    if task != id || Path::new(marker).exists() {
        return Ok(());
    }
    std::fs::write(marker, id)?;
    let _ = std::fs::write(path, &bytes[..bytes.len() / 2]);
    eprintln!("{FAULT_ENV}: task {id} killed half way");
    std::process::abort();
}

//! The method's TOML configuration (`[mesh]`, `[solver]`, `[export]`, `[scan]`, `[map]`; see
//! docs/config.md): raw structs that reject unknown keys, then a validation that reports
//! every problem at once with its key path. The `isoline` crate reads the daemon's and
//! batch jobs' tables around these.

use serde::Deserialize;
use std::path::Path;

use crate::error::{Error, Result};
use isoline_core::ExportParams;
use isoline_core::MeshParams;
use isoline_core::Params;
use isoline_core::ScanParams;
use isoline_core::SolverParams;
use isoline_core::{Init, Scheme};

/// An invalid configuration from `name`, with every problem found.
fn invalid(name: &str, problems: Vec<String>) -> Error {
    Error::Core(isoline_core::Error::Config {
        path: name.to_string(),
        problems,
    })
}

/// The whole configuration file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// `[mesh]`: the adapted mesh.
    #[serde(default)]
    pub mesh: MeshConfig,
    /// `[solver]`: the level-set evolution.
    #[serde(default)]
    pub solver: SolverConfig,
    /// `[export]`: the curves written.
    #[serde(default)]
    pub export: ExportConfig,
    /// `[scan]`: how frames seen from a sensor are read.
    #[serde(default)]
    pub scan: ScanConfig,
    /// `[map]`: `isoline map`'s world lattice.
    #[serde(default)]
    pub map: MapConfig,
    /// `[register]`: how `isoline map --register` and the daemon's `register = true`
    /// estimate poses (docs/method.md, "Poses"); every key optional, defaults as
    /// `isoline_map::RegisterParams::default()`.
    #[serde(default)]
    pub register: isoline_map::RegisterParams,
}

/// `[map]`: how `isoline map` fuses scans (docs/method.md, "A map of the whole run").
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapConfig {
    /// Spacing of the lattice's samples, metres. Default 0.03.
    pub cell: Option<f64>,
    /// Samples along a tile's side. Default 128.
    pub tile: Option<usize>,
    /// Scans whose curves must support a stretch before it enters the map. Default 2.
    pub min_scans: Option<u16>,
    /// Cap of the running average, in scans. Default 64.
    pub max_weight: Option<u16>,
    /// A beam's return within this of a sample hits it, metres. Default 0.05.
    pub hit_tolerance: Option<f64>,
    /// Beams count up to this range, metres. Default 20.
    pub max_range: Option<f64>,
    /// Tiles held in memory at most. Default 512.
    pub max_tiles: Option<usize>,
    /// Tiles kept in the spill folder at most; beyond it the least recently seen are
    /// forgotten. Default 8192 (2 GiB of 128-sample tiles).
    pub max_stored_tiles: Option<usize>,
    /// Lay each scan onto the map before fusing it. Default false.
    pub align: Option<bool>,
    /// Standard deviation of the poses' heading error, radians, in `[0, 0.5]`: a scan's
    /// walls count less the farther they lie from its sensor. Default 0.0087 (half a
    /// degree; 0: every scan alike).
    pub heading_noise: Option<f64>,
    /// The map's files, one path or a list (the extension picks the format: .geojson,
    /// .svg, .ndjson, .json, .mcap), relative to the configuration file's folder. The
    /// daemon maps the scans of its streams only when this is set; `isoline map` writes
    /// here when it has no `-o`.
    pub output: Option<OneOrMore>,
    /// Write the map every this many scans as it grows, in `0..=2^32` (0: only at the
    /// end). Default 0 for `isoline map`, 100 for the daemon.
    pub every: Option<u64>,
    /// Also write it when this many seconds have passed since the last write, in
    /// `[0.001, 1e6]` (the daemon only; checked as scans come in). Default: not by time.
    pub every_seconds: Option<f64>,
    /// Where tiles beyond `max_tiles` go, a folder. Default: a temporary folder in the
    /// system's.
    pub spill: Option<std::path::PathBuf>,
}

/// One path, or a list of them.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum OneOrMore {
    /// `key = "a.geojson"`.
    One(std::path::PathBuf),
    /// `key = ["a.geojson", "a.svg"]`.
    More(Vec<std::path::PathBuf>),
}

impl OneOrMore {
    /// The paths, in order.
    pub fn paths(&self) -> Vec<std::path::PathBuf> {
        match self {
            OneOrMore::One(p) => vec![p.clone()],
            OneOrMore::More(v) => v.clone(),
        }
    }
}

impl MapConfig {
    /// The map parameters, validated; every problem is listed.
    pub fn to_params(&self) -> std::result::Result<isoline_map::MapParams, Vec<String>> {
        let d = isoline_map::MapParams::default();
        let p = isoline_map::MapParams {
            cell: self.cell.unwrap_or(d.cell),
            tile: self.tile.unwrap_or(d.tile),
            min_scans: self.min_scans.unwrap_or(d.min_scans),
            max_weight: self.max_weight.unwrap_or(d.max_weight),
            hit_tolerance: self.hit_tolerance.unwrap_or(d.hit_tolerance),
            max_range: self.max_range.unwrap_or(d.max_range),
            max_tiles: self.max_tiles.unwrap_or(d.max_tiles),
            max_stored_tiles: self.max_stored_tiles.unwrap_or(d.max_stored_tiles),
            align: self.align.unwrap_or(d.align),
            heading_noise: self.heading_noise.unwrap_or(d.heading_noise),
        };
        let mut problems = p.validate().err().unwrap_or_default();
        for o in self.output.iter().flat_map(OneOrMore::paths) {
            if crate::map_files::MapFormat::of(&o).is_none() {
                problems.push(format!(
                    "map.output = {:?}: a map is written as {}",
                    o.display().to_string(),
                    crate::map_files::MAP_EXTENSIONS
                ));
            }
        }
        if matches!(&self.output, Some(OneOrMore::More(v)) if v.is_empty()) {
            problems.push("map.output = []: name at least one file, or leave it out".into());
        }
        if self.every.is_some_and(|n| n > 1 << 32) {
            problems.push(format!(
                "map.every = {}: must be in 0..=2^32 scans",
                self.every.unwrap_or(0)
            ));
        }
        if let Some(s) = self.every_seconds.filter(|s| !(0.001..=1e6).contains(s)) {
            problems.push(format!("map.every_seconds = {s}: must be in [0.001, 1e6]"));
        }
        if problems.is_empty() {
            Ok(p)
        } else {
            Err(problems)
        }
    }
}

/// `[scan]`: frames with beams, or points with a sensor `origin`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanConfig {
    /// Range noise (standard deviation, data units). Default: estimated per frame.
    pub range_noise: Option<f64>,
    /// Breakpoint test: surfaces seen at incidence above `90 - incidence_limit` degrees
    /// break into separate runs. Default 10.
    pub incidence_limit: Option<f64>,
    /// Runs of fewer returns are reported as features, not curves. Default 3.
    pub min_run: Option<usize>,
    /// At most this many consecutive beams without a return inside a run are dropouts.
    /// Default 2.
    pub dropout_beams: Option<usize>,
    /// Seconds from one beam to the next, for frames of beams that do not say
    /// (`time_increment` absent or 0): the scanner's period over its steps a turn (a
    /// Hokuyo URG-04LX: 0.1 s / 1024). Frames are then corrected for the sensor's motion
    /// during the sweep. Default: none, frames taken at once.
    pub time_increment: Option<f64>,
}

impl ScanConfig {
    /// The scan parameters, validated; every problem is listed.
    pub fn to_params(&self) -> std::result::Result<ScanParams, Vec<String>> {
        let d = ScanParams::default();
        let mut p = d.clone();
        p.range_noise = self.range_noise;
        p.incidence_limit = self.incidence_limit.unwrap_or(d.incidence_limit);
        p.min_run = self.min_run.unwrap_or(d.min_run);
        p.dropout_beams = self.dropout_beams.unwrap_or(d.dropout_beams);
        let timing = match self.time_increment {
            Some(t) if !(t.is_finite() && (0.0..=1.0).contains(&t)) => {
                Some(format!("scan.time_increment = {t}: must be 0 to 1 second"))
            }
            _ => None,
        };
        match (p.validate(), timing) {
            (Ok(()), None) => Ok(p),
            (Ok(()), Some(t)) => Err(vec![t]),
            (Err(mut e), t) => {
                e.extend(t);
                Err(e)
            }
        }
    }
}

/// `[solver]`. Unset values are derived from the data's diagonal `D` and `hmin`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverConfig {
    /// `"semi-implicit"` (default) or `"explicit"`.
    pub scheme: Option<String>,
    /// Attraction of eq. 4, an inverse length. Default `10 / D`.
    pub alpha: Option<f64>,
    /// Semi-implicit time step in units of `hmin`. Default 10.
    pub dt_factor: Option<f64>,
    /// Explicit: fraction of the stability bound, in (0, 1]. Default 0.9.
    pub cfl: Option<f64>,
    /// Explicit: per-vertex time steps. Default true.
    pub local_dt: Option<bool>,
    /// Stopping tolerance of eq. 11 (data units). Default `hmin`.
    pub eps: Option<f64>,
    /// Renormalize every this many steps; 0 never. Default 5 (semi-implicit), 100 (explicit).
    pub renormalize_every: Option<usize>,
    /// Iteration cap. Default 2,000 (semi-implicit), 200,000 (explicit).
    pub max_iterations: Option<usize>,
    /// A solver phase ends when the mean residual improves by less than 1% over this many
    /// steps. Default 10 (semi-implicit), 1,000 (explicit).
    pub patience: Option<usize>,
    /// Patience of a frame warm-started at the data (daemon). Default `patience / 2`.
    pub warm_patience: Option<usize>,
    /// Starting curve: `"medial"` (default), `"tube"`, `"box"` or `"circle"` (the paper's).
    pub init: Option<String>,
    /// After the capture phase on noisy data: `"median"` (default) or `"flow"`.
    pub settle: Option<String>,
    /// Tube start: radius of the tube around the data. Default: twice the 95th percentile
    /// of the nearest-neighbour spacing, at least `2 hmin`.
    pub tube: Option<f64>,
    /// Gap between the data and the starting curve, in units of `D`. Default 0.05.
    pub margin: Option<f64>,
    /// Narrow band half-width in units of `D`; 0 moves every vertex. Default 0.1.
    pub band: Option<f64>,
    /// Semi-implicit linear solver: `"cg"` (default) or `"gmres"` (the paper's).
    pub linear_solver: Option<String>,
    /// Its residual reduction per step, in (0, 1). Default 1e-2.
    pub linear_tolerance: Option<f64>,
    /// Its iterations per step, 1..=1000. Default 10.
    pub linear_max_iterations: Option<usize>,
}

/// `[export]`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportConfig {
    /// Douglas-Peucker tolerance in data units; 0 (default) keeps every vertex.
    pub simplify: Option<f64>,
    /// Closed loops enclosing less area are dropped (default pi (3 hmin)^2; 0 keeps all).
    pub min_area: Option<f64>,
    /// `[export.repair]`: the point-cloud repair passes' tolerances, each a multiple of
    /// `hmin`, a count of samples, an angle or a ratio (docs/method.md, "The repair
    /// stage"); unset ones keep their defaults.
    pub repair: Option<isoline_core::RepairTolerances>,
}

/// TOML text as a table, or the parser's message (its lines indented, as one of a list
/// of problems).
pub fn parse_table(text: &str) -> std::result::Result<toml::Table, String> {
    toml::from_str(text).map_err(|e: toml::de::Error| e.to_string().trim().replace('\n', "\n  "))
}

/// Reads `value` as a `T`; on failure adds the problem, with its key path under
/// `prefix` (`"input."`), to `problems`.
pub fn read_value<T: serde::de::DeserializeOwned>(
    value: toml::Value,
    prefix: &str,
    problems: &mut Vec<String>,
) -> Option<T> {
    value
        .try_into()
        .map_err(|e| problems.push(value_problem(&e, prefix)))
        .ok()
}

/// Takes the table `key` out of `t`: an empty table when absent, and a problem naming
/// `key` when it is not a table.
pub fn take_table(t: &mut toml::Table, key: &str, problems: &mut Vec<String>) -> toml::Table {
    match t.remove(key) {
        None => toml::Table::new(),
        Some(toml::Value::Table(table)) => table,
        Some(other) => {
            problems.push(format!("{key} = {other}: expected a table"));
            toml::Table::new()
        }
    }
}

/// A deserialisation error of an already-parsed TOML value as `prefix.key: message`
/// (toml reports the key on a line of its own, as ``in `key` ``).
pub fn value_problem(e: &toml::de::Error, prefix: &str) -> String {
    let text = e.to_string();
    let text = text.trim();
    match text.rsplit_once("\nin `") {
        Some((msg, key)) => format!("{prefix}{}: {}", key.trim_end_matches('`'), msg.trim()),
        None if prefix.is_empty() => text.to_string(),
        None => format!("{}: {text}", prefix.trim_end_matches('.')),
    }
}

impl SolverConfig {
    /// The solver parameters, validated; every problem is listed.
    pub fn to_params(&self) -> std::result::Result<SolverParams, Vec<String>> {
        let mut problems = Vec::new();
        let mut p = SolverParams::default();
        if let Some(s) = &self.scheme {
            match s.parse::<Scheme>() {
                Ok(s) => p.scheme = s,
                Err(e) => problems.push(format!("solver.scheme: {e}")),
            }
        }
        if let Some(s) = &self.linear_solver {
            match s.parse::<isoline_core::LinearSolver>() {
                Ok(l) => p.linear = l,
                Err(e) => problems.push(format!("solver.linear_solver: {e}")),
            }
        }
        if let Some(s) = &self.settle {
            match s.parse::<isoline_core::Settle>() {
                Ok(v) => p.settle = v,
                Err(e) => problems.push(format!("solver.settle: {e}")),
            }
        }
        if let Some(s) = &self.init {
            match s.parse::<Init>() {
                Ok(i) => p.init = i,
                Err(e) => problems.push(format!("solver.init: {e}")),
            }
        }
        p.alpha = self.alpha;
        p.dt_factor = self.dt_factor;
        p.cfl = self.cfl.unwrap_or(p.cfl);
        p.local_dt = self.local_dt.unwrap_or(p.local_dt);
        p.eps = self.eps;
        p.renormalize_every = self.renormalize_every;
        p.max_iterations = self.max_iterations;
        p.patience = self.patience;
        p.warm_patience = self.warm_patience;
        p.margin = self.margin.unwrap_or(p.margin);
        p.tube = self.tube;
        p.linear_tolerance = self.linear_tolerance.unwrap_or(p.linear_tolerance);
        p.linear_max_iterations = self
            .linear_max_iterations
            .unwrap_or(p.linear_max_iterations);
        p.band = self.band.unwrap_or(p.band);
        if let Err(more) = p.validate() {
            problems.extend(more);
        }
        if problems.is_empty() {
            Ok(p)
        } else {
            Err(problems)
        }
    }
}

impl ExportConfig {
    /// The export parameters, validated.
    pub fn to_params(&self) -> std::result::Result<ExportParams, Vec<String>> {
        let simplify = self.simplify.unwrap_or(0.0);
        if !(simplify.is_finite() && simplify >= 0.0) {
            return Err(vec![format!(
                "export.simplify = {simplify}: must be a finite number >= 0"
            )]);
        }
        if let Some(a) = self.min_area {
            if !(a.is_finite() && a >= 0.0) {
                return Err(vec![format!(
                    "export.min_area = {a}: must be a finite number >= 0"
                )]);
            }
        }
        let mut p = ExportParams::default();
        p.simplify = simplify;
        p.min_area = self.min_area;
        if let Some(t) = &self.repair {
            t.validate()?;
            p.repair = t.clone();
        }
        Ok(p)
    }
}

/// `[mesh]`. Lengths are in data units; unset ones are derived from the data's
/// bounding-box diagonal `D`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshConfig {
    /// Smallest element size, across the data. Default `D / 1000`.
    pub hmin: Option<f64>,
    /// Largest element size. Default `D / 10`.
    pub hmax: Option<f64>,
    /// Geometric tolerance of the size along the data. Default `hmin`.
    pub eps: Option<f64>,
    /// Half-width of the finely meshed band around the data. Default `max(8 hmin, 4 noise)`.
    pub band: Option<f64>,
    /// Size growth per unit distance outside the band. Default 0.3.
    pub gradation: Option<f64>,
    /// Samples per local curve fit. Default 32.
    pub neighbours: Option<usize>,
    /// Margin around the data as a fraction of `D`. Default 0.2.
    pub padding: Option<f64>,
    /// Isotropic size `hmin` in the band (comparison mesh). Default false.
    pub isotropic: Option<bool>,
    /// Most adaptation passes. Default 24.
    pub max_passes: Option<usize>,
    /// A warm adaptation (daemon) stops after a pass changing less than this fraction of
    /// the vertices. Default 0.35.
    pub warm_change: Option<f64>,
    /// Most vertices. Default 2,000,000.
    pub max_vertices: Option<usize>,
}

impl MeshConfig {
    /// The mesh parameters, validated; every problem is listed.
    pub fn to_params(&self) -> std::result::Result<MeshParams, Vec<String>> {
        let mut p = MeshParams::default();
        p.hmin = self.hmin;
        p.hmax = self.hmax;
        p.eps = self.eps;
        p.band = self.band;
        p.gradation = self.gradation.or(p.gradation);
        p.neighbours = self.neighbours.unwrap_or(p.neighbours);
        p.padding = self.padding.unwrap_or(p.padding);
        p.isotropic = self.isotropic.unwrap_or(p.isotropic);
        p.max_passes = self.max_passes.unwrap_or(p.max_passes);
        p.warm_change = self.warm_change.unwrap_or(p.warm_change);
        p.max_vertices = self.max_vertices.unwrap_or(p.max_vertices);
        p.validate().map(|()| p)
    }
}

impl Config {
    /// Parses and validates TOML text; `name` labels errors.
    pub fn parse(text: &str, name: &str) -> Result<Config> {
        let table = parse_table(text).map_err(|e| invalid(name, vec![e]))?;
        Config::from_table(table, name, "")
    }

    /// Builds and validates a configuration from parsed TOML (the `[mesh]`, `[solver]`
    /// and `[export]` tables); `prefix` is put before every key path in messages.
    pub fn from_table(table: toml::Table, name: &str, prefix: &str) -> Result<Config> {
        let mut problems = Vec::new();
        let cfg: Config = read_value(toml::Value::Table(table), prefix, &mut problems)
            .ok_or_else(|| invalid(name, problems))?;
        cfg.validate(name, prefix)
    }

    fn validate(self, name: &str, prefix: &str) -> Result<Config> {
        let cfg = self;
        let mut problems = Vec::new();
        if let Err(p) = cfg.mesh.to_params() {
            problems.extend(p);
        }
        if let Err(p) = cfg.solver.to_params() {
            problems.extend(p);
        }
        if let Err(p) = cfg.export.to_params() {
            problems.extend(p);
        }
        if let Err(p) = cfg.scan.to_params() {
            problems.extend(p);
        }
        match cfg.map.to_params() {
            Err(p) => problems.extend(p),
            // The map takes a scan's noise as at most this wide: a configured noise
            // beyond it is a mistake (no laser scanner is that noisy), said now.
            Ok(_) if cfg.map.output.is_some() => problems.extend(cfg.map_noise_problem()),
            Ok(_) => {}
        }
        if let Err(p) = cfg.register.validate() {
            problems.extend(p);
        }
        if !problems.is_empty() {
            return Err(invalid(
                name,
                problems
                    .into_iter()
                    .map(|p| format!("{prefix}{p}"))
                    .collect(),
            ));
        }
        Ok(cfg)
    }

    /// Why `[scan] range_noise` is too wide for the map, if it is: the map takes a
    /// scan's noise as at most `(max_tolerance - 2 cell) / 3` (a wider one would reach
    /// tiles beyond those its bound counts), and no laser scanner is that noisy. Checked
    /// at load when `[map] output` is set, and by whatever else maps.
    pub fn map_noise_problem(&self) -> Option<String> {
        let map = self.map.to_params().ok()?;
        let widest = (map.max_tolerance() - 2.0 * map.cell) / 3.0;
        let n = self.scan.range_noise.filter(|n| *n > widest)?;
        Some(format!(
            "scan.range_noise = {n}: at most {widest:.3} m with the map's cell and tile \
             (3 range_noise + 2 cell within a quarter of a tile's side, or ten cells)"
        ))
    }

    /// Reads and validates a TOML file.
    pub fn load(path: &Path) -> Result<Config> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Config::parse(&text, &path.display().to_string())
    }

    /// The validated mesh parameters.
    pub fn mesh_params(&self) -> MeshParams {
        self.mesh.to_params().expect("validated when loaded")
    }

    /// The validated map parameters.
    pub fn map_params(&self) -> isoline_map::MapParams {
        self.map.to_params().expect("validated when loaded")
    }

    /// All reconstruction parameters, validated when loaded.
    pub fn params(&self) -> Params {
        let mut p = Params::new(
            self.mesh_params(),
            self.solver.to_params().expect("validated when loaded"),
            self.export.to_params().expect("validated when loaded"),
        );
        p.scan = self.scan.to_params().expect("validated when loaded");
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        // Each refused file, and what its error must name.
        let refused: [(&str, &str, &[&str]); 10] = [
            (
                "a.toml",
                "[mesh]\nhmin = 0.001\nhmni = 2\n",
                &["a.toml", "hmni"],
            ),
            (
                "b.toml",
                "[mesh]\nhmin = -1\nhmax = 0.0\nneighbours = 1\n",
                &["mesh.hmin = -1", "mesh.hmax = 0", "mesh.neighbours = 1"],
            ),
            ("c.toml", "[mesh]\nhmin = \"small\"\n", &["c.toml", "hmin"]),
            (
                "e.toml",
                "[solver]\nscheme = \"implicit\"\ncfl = 2.0\n[export]\nsimplify = -1\n",
                &["solver.scheme", "solver.cfl = 2", "export.simplify"],
            ),
            (
                "g.toml",
                "[scan]\nmin_run = 0\nincidence_limit = 95\ntime_increment = -1\n",
                &[
                    "scan.min_run = 0",
                    "scan.incidence_limit = 95",
                    "scan.time_increment = -1",
                ],
            ),
            (
                "r.toml",
                "[export.repair]\nthrough_frame = 0\nclean_fit = -1\n",
                &["export.repair.through_frame", "export.repair.clean_fit"],
            ),
            ("u.toml", "[export.repair]\ncleanfit = 0.5\n", &["cleanfit"]),
            ("f.toml", "[solver]\nalhpa = 1\n", &["alhpa"]),
            (
                "p.toml",
                "[register]\nnoise = -1\nmax_keyframes = 3\n",
                &["register.noise = -1", "register.max_keyframes = 3"],
            ),
            ("q.toml", "[register]\nloop = false\n", &["loop"]),
        ];
        for (name, text, names) in refused {
            let e = Config::parse(text, name).unwrap_err().to_string();
            assert!(names.iter().all(|n| e.contains(n)), "{name}: {e}");
        }
        let c = Config::parse("[export.repair]\nclean_fit = 0.5\n", "ok.toml").unwrap();
        let repair = &c.params().export.repair;
        assert_eq!(repair.clean_fit, 0.5);
        assert_eq!(
            repair.through_frame,
            isoline_core::RepairTolerances::default().through_frame
        );
        for shipped in ["example.toml", "paper-4.1.toml", "circle-hmin1e-3.toml"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../config")
                .join(shipped);
            Config::load(&path).unwrap().params();
        }
        let ok = Config::parse("[mesh]\nhmin = 1e-3\neps = 1e-3\n", "d.toml").unwrap();
        assert_eq!(ok.mesh_params().hmin, Some(1e-3));
    }
}

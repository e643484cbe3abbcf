//! The TOML configuration: raw structs that reject unknown keys, then a validation that
//! reports every problem at once with its key path.

use serde::Deserialize;
use std::path::Path;

use crate::error::{Error, Result};
use crate::meshing::MeshParams;

/// The whole configuration file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// `[mesh]`: the adapted mesh.
    #[serde(default)]
    pub mesh: MeshConfig,
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
    /// Samples per local curve fit. Default 16.
    pub neighbours: Option<usize>,
    /// Margin around the data as a fraction of `D`. Default 0.2.
    pub padding: Option<f64>,
    /// Isotropic size `hmin` in the band (comparison mesh). Default false.
    pub isotropic: Option<bool>,
    /// Most adaptation passes. Default 24.
    pub max_passes: Option<usize>,
    /// Most vertices. Default 2,000,000.
    pub max_vertices: Option<usize>,
}

impl MeshConfig {
    /// The mesh parameters, validated; every problem is listed.
    pub fn to_params(&self) -> std::result::Result<MeshParams, Vec<String>> {
        let d = MeshParams::default();
        let p = MeshParams {
            hmin: self.hmin,
            hmax: self.hmax,
            eps: self.eps,
            band: self.band,
            gradation: self.gradation.unwrap_or(d.gradation),
            neighbours: self.neighbours.unwrap_or(d.neighbours),
            padding: self.padding.unwrap_or(d.padding),
            isotropic: self.isotropic.unwrap_or(d.isotropic),
            max_passes: self.max_passes.unwrap_or(d.max_passes),
            max_vertices: self.max_vertices.unwrap_or(d.max_vertices),
        };
        p.validate().map(|()| p)
    }
}

impl Config {
    /// Parses and validates TOML text; `name` labels errors.
    pub fn parse(text: &str, name: &str) -> Result<Config> {
        let cfg: Config = toml::from_str(text).map_err(|e| Error::Config {
            path: name.to_string(),
            problems: vec![e.to_string().trim().replace('\n', "\n  ")],
        })?;
        cfg.mesh.to_params().map_err(|problems| Error::Config {
            path: name.to_string(),
            problems,
        })?;
        Ok(cfg)
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let e = Config::parse("[mesh]\nhmin = 0.001\nhmni = 2\n", "a.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.toml") && e.contains("hmni"), "{e}");
        let e = Config::parse("[mesh]\nhmin = -1\nhmax = 0.0\nneighbours = 1\n", "b.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("mesh.hmin = -1")
                && e.contains("mesh.hmax = 0")
                && e.contains("mesh.neighbours = 1"),
            "{e}"
        );
        let e = Config::parse("[mesh]\nhmin = \"small\"\n", "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.toml") && e.contains("hmin"), "{e}");
        let ok = Config::parse("[mesh]\nhmin = 1e-3\neps = 1e-3\n", "d.toml").unwrap();
        assert_eq!(ok.mesh_params().hmin, Some(1e-3));
    }
}

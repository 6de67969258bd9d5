//! The map products of a suite: the mapped mesh offset by `--origin` when
//! given, encoded with the mapping views its distances are measured to.

use super::protocol::TILE_M;
use crate::error::{Error, Result};
use crate::io::mesh::MeshData;
use crate::mapscore;
use crate::relight::{relit_mesh, RelightOptions, SunAngles};
use crate::render::Sun;
use std::borrow::Cow;
use std::sync::Arc;
use vtsm_core::geom::Pose;

/// One map product and the mapping views its distances are measured to.
pub struct MapEntry {
    /// The encoded map, or why it could not be encoded.
    pub bytes: std::result::Result<Vec<u8>, String>,
    /// The mapping views.
    pub views: Vec<Pose>,
    /// The map's origin (user frame = the scene offset by `--origin`).
    pub origin: [f64; 3],
    /// The decile of each mask vertex's sampling score, by mask index
    /// (empty unless asked for: `--score-deciles`).
    pub deciles: Vec<u8>,
    /// The mesh the product was encoded from and the sun it was mapped
    /// under, kept for `--relight on` ([`MapEntry::relit`]).
    pub source: Option<(Arc<MeshData>, SunAngles)>,
}

/// What a suite's maps carry beyond the mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Scoring {
    /// Ship sampling scores in the product (version 3).
    pub scores: bool,
    /// Keep each mask vertex's score decile ([`MapEntry::deciles`]).
    pub deciles: bool,
}

impl Scoring {
    /// What `cfg` asks for.
    pub fn of(cfg: &super::config::SuiteConfig) -> Self {
        Self {
            scores: cfg.map_scores,
            deciles: cfg.score_deciles,
        }
    }
}

impl MapEntry {
    /// Encode `mesh` (offset by `offset` when given) with its mapping
    /// `views`, scored as `scoring` asks.
    pub fn encode(
        mesh: &MeshData,
        offset: Option<[f64; 3]>,
        views: Vec<Pose>,
        scoring: Scoring,
    ) -> Self {
        let terms = (scoring.scores || scoring.deciles)
            .then(|| mapscore::vertex_terms(mesh, &mapscore::ScoreOptions::default()));
        let scores = terms
            .as_ref()
            .filter(|_| scoring.scores)
            .map(|t| mapscore::scale(mesh, t));
        let deciles = terms
            .as_ref()
            .filter(|_| scoring.deciles)
            .map(|t| mapscore::mask_deciles(mesh, t))
            .unwrap_or_default();
        let (bytes, origin) = encode_entry(mesh, offset, scores.as_deref());
        Self {
            bytes,
            views,
            origin,
            deciles,
            source: None,
        }
    }

    /// Keep `mesh` and its mapping `sun` for relighting when `keep`
    /// (`--relight on`).
    pub fn with_source(self, mesh: &MeshData, sun: &Sun, keep: bool) -> Self {
        Self {
            source: keep.then(|| (Arc::new(mesh.clone()), SunAngles::from(sun))),
            ..self
        }
    }

    /// This map relit to `sun` and encoded as `scoring` asks, with the same
    /// views (or why it could not be relit, as the entry's bytes); `None`
    /// when no source was kept.
    pub fn relit(&self, sun: &Sun, scoring: Scoring, offset: Option<[f64; 3]>) -> Option<Self> {
        let (mesh, map_sun) = self.source.as_ref()?;
        let opts = RelightOptions::default();
        Some(match relit_mesh(mesh, *map_sun, sun.into(), &opts) {
            Ok((m, _)) => Self::encode(&m, offset, self.views.clone(), scoring),
            Err(e) => Self {
                bytes: Err(format!("relighting: {e}")),
                views: self.views.clone(),
                origin: self.origin,
                deciles: Vec::new(),
                source: None,
            },
        })
    }
}

/// `mesh` (simulator frame) offset by `offset` and re-expressed as the file
/// readers do: f64 vertices in the offset frame, f32 vertices relative to
/// `origin` (`None`: the default origin, [`crate::frame::default_origin`]).
///
/// # Errors
/// An unusable origin, or a vertex out of f32 range about it.
pub fn offset_mesh(
    mesh: &MeshData,
    offset: [f64; 3],
    origin: Option<[f64; 3]>,
) -> Result<MeshData> {
    let user: Vec<[f64; 3]> = mesh
        .vertices
        .iter()
        .map(|v| [0, 1, 2].map(|k| f64::from(v[k]) + mesh.origin[k] + offset[k]))
        .collect();
    let origin = origin.unwrap_or_else(|| crate::frame::default_origin(&user));
    let vertices = crate::frame::local_vertices(&user, origin).map_err(Error::msg)?;
    Ok(MeshData {
        vertices,
        origin,
        ..mesh.clone()
    })
}

/// Encode a suite's map, offset by `--origin` when given; the bytes (or why
/// not) and the map's origin.
fn encode_entry(
    mesh: &MeshData,
    offset: Option<[f64; 3]>,
    scores: Option<&[u8]>,
) -> (std::result::Result<Vec<u8>, String>, [f64; 3]) {
    let mesh = match offset {
        None => Cow::Borrowed(mesh),
        Some(o) => match offset_mesh(mesh, o, Some(o)) {
            Ok(m) => Cow::Owned(m),
            Err(e) => return (Err(e.to_string()), [0.0; 3]),
        },
    };
    (
        mesh.encode_scored_map(TILE_M, scores)
            .map_err(|e| e.to_string()),
        mesh.origin,
    )
}

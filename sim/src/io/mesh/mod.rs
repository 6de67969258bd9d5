//! The in-memory textured mesh ([`MeshData`]) shared by the file readers and
//! the simulator's mapping stage, and its conversion to a map product.
//!
//! Readers produce a [`RawMesh`] (geometry plus whatever appearance the file
//! had); [`MeshData::from_raw`] turns it into a mesh that always has a gray
//! texture and per-corner texture coordinates:
//!
//! * texture + texture coordinates: used as they are;
//! * per-vertex colour and no texture: a texture atlas is synthesised
//!   ([`synthesize_atlas`]): every triangle gets its own
//!   [`ATLAS_CELL_PX`]² cell, painted with the barycentric interpolation of
//!   its three vertex grays, its corners at pixel centres of the cell so that
//!   bilinear sampling anywhere inside the triangle reads only its own cell;
//! * neither: an error.
//!
//! Texture coordinates are normalised and follow OBJ: `u = 0` is the left edge
//! of the texture image, `v = 0` its bottom edge; texel `(i, j)` (column,
//! row from the top) has its centre at `u = (i + 0.5) / W`, `v = 1 − (j + 0.5) / H`.
//!
//! Readers keep vertex coordinates in f64, in the file's own (user) frame;
//! [`MeshData::from_raw_at`] chooses the map origin (given, or
//! [`crate::frame::default_origin`]) and stores the vertices relative to it as
//! f32 ([`crate::frame::local_vertices`]), the only f64 → f32 conversion.
//!
//! The sampling mask M̂ ([`MeshData::apply_mask`]) marks the triangles of the
//! mesh that coincide with a triangle of a mask mesh K: vertices are matched by
//! position within [`MASK_MATCH_TOL_M`], triangles as unordered vertex triples.
//!
//! Files: [`raw`] (what a reader gives, and the capacity check every reader
//! makes), [`data`] (the textured mesh and its map product), [`load`] (the
//! one reader of every mesh form, by extension).

pub mod data;
pub mod load;
pub mod raw;

pub use data::{bounds_of, synthesize_atlas, MaskStats, MeshData, ATLAS_CELL_PX, MASK_MATCH_TOL_M};
pub use load::{load_geometry, load_mesh, load_mesh_at, load_mesh_with_progress};
pub use raw::{check_capacity, CornerUvs, RawMesh};

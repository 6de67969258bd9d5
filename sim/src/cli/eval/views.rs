//! What a mapping view sees: the map restricted to a sub-sampled mapping path.

use super::protocol::MAP_VIEW_RANGE_M;
use crate::io::mesh::MeshData;
use vtsm_core::geom::{Camera, Pose, Vec3};

/// Whether the triangle `(a, b, c)` is seen by a camera `cam` at `world_from_cam`:
/// centroid in front, within `range_m`, inside the image, and the triangle's
/// upward-oriented normal facing the camera. Occlusion is not tested.
pub fn seen_by(cam: &Camera, world_from_cam: &Pose, tri: [Vec3; 3], range_m: f32) -> bool {
    let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
    let eye = world_from_cam.translation();
    let to_eye = eye - centroid;
    if to_eye.norm() > range_m {
        return false;
    }
    let mut n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    if n.z < 0.0 {
        n = -n;
    }
    if n.dot(&to_eye) <= 0.0 {
        return false;
    }
    let p = world_from_cam.inverse().transform_point(&centroid);
    if p.z <= 0.0 {
        return false;
    }
    cam.project(&p)
        .is_some_and(|[u, v]| cam.contains(u, v, 0.0))
}

/// The map as the views would have made it: keep only triangles [`seen_by`] at
/// least one view within [`MAP_VIEW_RANGE_M`]; vertices and texture are kept
/// whole (unreferenced vertices cost nothing to the core).
pub fn restrict_to_views(mesh: &MeshData, cam: &Camera, views: &[Pose]) -> MeshData {
    let mut out = MeshData {
        vertices: mesh.vertices.clone(),
        triangles: Vec::new(),
        uvs: Vec::new(),
        mask: Vec::new(),
        texture: mesh.texture.clone(),
        origin: mesh.origin,
    };
    let vert = |i: u32| {
        mesh.vertices
            .get(i as usize)
            .map_or(Vec3::zeros(), |p| Vec3::new(p[0], p[1], p[2]))
    };
    for ((t, uv), m) in mesh.triangles.iter().zip(&mesh.uvs).zip(&mesh.mask) {
        let tri = [vert(t[0]), vert(t[1]), vert(t[2])];
        if views.iter().any(|v| seen_by(cam, v, tri, MAP_VIEW_RANGE_M)) {
            out.triangles.push(*t);
            out.uvs.push(*uv);
            out.mask.push(*m);
        }
    }
    out
}

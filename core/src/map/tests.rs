extern crate std;
use super::format::*;
use super::*;
use crate::config::{MAX_MAP_ORIGIN_M, MAX_MAP_VERTICES};
use crate::failure::FailureCode;
use crate::geom::Vec3;
use crate::image::GrayView;
use proptest::prelude::*;
use std::boxed::Box;
use std::collections::BTreeSet;
use std::vec;
use std::vec::Vec;

/// A test mesh in memory: an `n × n` grid of quads (two triangles each) over a
/// bumpy heightfield, `step` metres apart, with the triangles of the centre
/// rows in the mask.
pub(crate) struct Mesh {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub uvs: Vec<[[f32; 2]; 3]>,
    pub mask: Vec<bool>,
    pub tex: Vec<u8>,
    pub tex_w: usize,
    pub tex_h: usize,
}

impl Mesh {
    pub fn grid(n: usize, step: f32) -> Self {
        let mut vertices = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 * step, j as f32 * step);
                let z = 0.1 * libm::sinf(x * 1.3) * libm::cosf(y * 0.7);
                vertices.push([x, y, z]);
            }
        }
        let (mut triangles, mut uvs, mut mask) = (Vec::new(), Vec::new(), Vec::new());
        let uv = |i: usize, j: usize| [i as f32 / n as f32, j as f32 / n as f32];
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32 + 2);
                triangles.push([a, b, d]);
                uvs.push([uv(i, j), uv(i + 1, j), uv(i + 1, j + 1)]);
                triangles.push([a, d, c]);
                uvs.push([uv(i, j), uv(i + 1, j + 1), uv(i, j + 1)]);
                let m = j >= n / 3 && j < 2 * n / 3;
                mask.push(m);
                mask.push(m && i % 2 == 0);
            }
        }
        let (tex_w, tex_h) = (16, 12);
        let tex = (0..tex_w * tex_h).map(|k| (k * 37 % 251) as u8).collect();
        Self {
            vertices,
            triangles,
            uvs,
            mask,
            tex,
            tex_w,
            tex_h,
        }
    }

    pub fn source(&self, tile_size_m: f32) -> MapSource<'_> {
        MapSource {
            vertices: &self.vertices,
            triangles: &self.triangles,
            uvs: &self.uvs,
            mask: &self.mask,
            texture: GrayView::new(&self.tex, self.tex_w, self.tex_h, self.tex_w).unwrap(),
            tile_size_m,
            origin: [0.0; 3],
            vertex_scores: None,
        }
    }

    pub fn encode(&self, tile_size_m: f32) -> Vec<u8> {
        encode_src(&self.source(tile_size_m))
    }

    /// Sampling scores for every vertex: a repeating pattern with zeros, the
    /// largest score and small ones.
    pub fn scores(&self) -> Vec<u8> {
        (0..self.vertices.len())
            .map(|k| [0, 1, 255, 17, 0, 128, 3][k % 7])
            .collect()
    }

    /// The version-3 product of this mesh with `scores`.
    pub fn encode_scored(&self, tile_size_m: f32, scores: &[u8]) -> Vec<u8> {
        encode_src(&MapSource {
            vertex_scores: Some(scores),
            ..self.source(tile_size_m)
        })
    }
}

fn encode_src(src: &MapSource) -> Vec<u8> {
    let mut out = vec![0u8; encoded_len(src).unwrap()];
    let n = encode(src, &mut out).unwrap();
    out.truncate(n);
    out
}

fn section_off(bytes: &[u8], i: usize) -> usize {
    rd_u32(bytes, ENTRY_OFF[i]).unwrap() as usize
}

#[test]
fn crc32_matches_the_standard_check_value() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

/// The slicing-by-8 CRC equals the bitwise definition (reflected polynomial
/// 0xEDB88320) at every length 0..=64 and every alignment of the tail, and on a
/// long buffer.
#[test]
fn crc32_equals_the_bitwise_definition_at_every_length() {
    fn bitwise(bytes: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    let mut rng = crate::rng::Rng::new(9);
    let buf: Vec<u8> = (0..10_000).map(|_| (rng.next_u32() >> 24) as u8).collect();
    for n in 0..=64 {
        for start in 0..8 {
            let b = &buf[start..start + n];
            assert_eq!(crc32(b), bitwise(b), "length {n} from {start}");
        }
    }
    assert_eq!(crc32(&buf), bitwise(&buf));
}

/// Verifies: VTSM-MAP-001, VTSM-MAP-005, VTSM-MAP-006
#[test]
fn round_trip_preserves_mesh_tiles_texture_and_mask() {
    let mesh = Mesh::grid(9, 0.5);
    let bytes = mesh.encode(1.0);
    let map = MapView::new_checked(&bytes).unwrap();
    assert_eq!(map.vertex_count() as usize, mesh.vertices.len());
    assert_eq!(map.triangle_count() as usize, mesh.triangles.len());
    for (i, p) in mesh.vertices.iter().enumerate() {
        assert_eq!(map.vertex(i as u32).unwrap(), Vec3::new(p[0], p[1], p[2]));
    }
    assert_eq!(map.vertex(map.vertex_count()), None);
    assert_eq!(map.triangle(map.triangle_count()), None);
    // Every source triangle appears exactly once, with converted UVs and its mask bit.
    let key = |v: [u32; 3], uv: [[f32; 2]; 3], m: bool| {
        let uvb: Vec<u32> = uv.iter().flatten().map(|f| f.to_bits()).collect();
        (v, uvb, m)
    };
    let mut expected: Vec<_> = mesh
        .triangles
        .iter()
        .zip(&mesh.uvs)
        .zip(&mesh.mask)
        .map(|((t, uv), m)| {
            let px = uv.map(|c| [c[0] * 16.0 - 0.5, (1.0 - c[1]) * 12.0 - 0.5]);
            key(*t, px, *m)
        })
        .collect();
    let mut got: Vec<_> = (0..map.triangle_count())
        .map(|i| {
            let t = map.triangle(i).unwrap();
            key(t.v, t.uv, t.mask)
        })
        .collect();
    expected.sort();
    got.sort();
    assert_eq!(expected, got);
    // Tiles: contiguous runs covering all triangles, boxes bound them, centroid in cell.
    let (tx, ty, ts) = map.tile_grid();
    assert_eq!((tx, ty, ts), (5, 5, 1.0));
    let mut next = 0;
    for k in 0..map.tile_count() {
        let tile = map.tile(k).unwrap();
        assert_eq!(tile.first_triangle, next);
        next += tile.triangle_count;
        for i in tile.first_triangle..tile.first_triangle + tile.triangle_count {
            let t = map.triangle(i).unwrap();
            let ps: Vec<Vec3> = t.v.iter().map(|v| map.vertex(*v).unwrap()).collect();
            for p in &ps {
                assert!(p >= &tile.min && p <= &tile.max || inside(p, &tile.min, &tile.max));
            }
            let c = (ps[0] + ps[1] + ps[2]) / 3.0;
            let cell = (libm::floorf(c.y / ts) as u32).min(ty - 1) * tx
                + (libm::floorf(c.x / ts) as u32).min(tx - 1);
            assert_eq!(cell, k);
        }
    }
    assert_eq!(next, map.triangle_count());
    // Mask vertices: the set of vertices of mask triangles, increasing.
    let want: BTreeSet<u32> = mesh
        .triangles
        .iter()
        .zip(&mesh.mask)
        .filter(|(_, m)| **m)
        .flat_map(|(t, _)| t.iter().copied())
        .collect();
    let have: Vec<u32> = (0..map.mask_vertex_count())
        .map(|k| map.mask_vertex(k).unwrap())
        .collect();
    assert_eq!(have, want.into_iter().collect::<Vec<_>>());
    // Texture.
    let tex = map.texture();
    assert_eq!((tex.width(), tex.height()), (16, 12));
    for y in 0..12 {
        assert_eq!(tex.row(y).unwrap(), &mesh.tex[y * 16..(y + 1) * 16]);
    }
}

/// Verifies: VTSM-MAP-002, VTSM-MAP-011
#[test]
fn every_truncation_is_rejected_as_truncated() {
    let mesh = Mesh::grid(4, 0.5);
    let v3 = mesh.encode_scored(0.7, &mesh.scores());
    for bytes in [mesh.encode(0.7), v3] {
        let version = rd_u32(&bytes, 8).unwrap();
        for len in 0..bytes.len() {
            assert_eq!(
                MapView::new_checked(&bytes[..len]).err(),
                Some(FailureCode::MapTruncated),
                "version {version} len {len}"
            );
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(
            MapView::new_checked(&longer).err(),
            Some(FailureCode::MapInconsistent),
            "version {version}"
        );
    }
}

/// Verifies: VTSM-MAP-003, VTSM-MAP-011
#[test]
fn every_single_byte_flip_is_rejected() {
    let mesh = Mesh::grid(3, 0.5);
    let v3 = mesh.encode_scored(0.7, &mesh.scores());
    for bytes in [mesh.encode(0.7), v3] {
        let version = rd_u32(&bytes, 8).unwrap();
        assert!(MapView::new_checked(&bytes).is_ok());
        for pos in 0..bytes.len() {
            let mut b = bytes.clone();
            b[pos] ^= 0xFF;
            assert!(
                MapView::new_checked(&b).is_err(),
                "version {version} byte {pos} accepted"
            );
        }
    }
}

proptest! {
    /// Verifies: VTSM-MAP-003, VTSM-MAP-011
    #[test]
    fn any_single_byte_corruption_is_rejected(
        seed in 0usize..1_000_000,
        xor in 1u8..=255,
        scored in any::<bool>(),
    ) {
        let mesh = Mesh::grid(5, 0.4);
        let bytes = if scored {
            mesh.encode_scored(0.5, &mesh.scores())
        } else {
            mesh.encode(0.5)
        };
        let mut b = bytes.clone();
        let pos = seed % b.len();
        b[pos] ^= xor;
        prop_assert!(
            MapView::new_checked(&b).is_err(),
            "scored {} pos {} xor {}", scored, pos, xor
        );
    }
}

/// Verifies: VTSM-MAP-004
#[test]
fn each_kind_of_inconsistency_has_its_own_code() {
    let good = Mesh::grid(4, 0.5).encode(1.0);
    let tri = section_off(&good, SEC_TRIANGLES);
    let vert = section_off(&good, SEC_VERTICES);
    let tiles = section_off(&good, SEC_TILES);
    let nv = rd_u32(&good, 16).unwrap();
    type Edit = fn(&mut Vec<u8>, usize, usize, usize, u32);
    let cases: &[(Edit, FailureCode)] = &[
        (|b, _, _, _, _| b[0] = b'X', FailureCode::MapBadMagic),
        (|b, _, _, _, _| b[8] = 4, FailureCode::MapUnsupportedVersion),
        (
            |b, t, _, _, nv| wr_u32(b, t + 4, nv).unwrap(),
            FailureCode::MapIndexOutOfRange,
        ),
        (
            |b, _, v, _, _| wr_f32(b, v, f32::NAN).unwrap(),
            FailureCode::MapNonFinite,
        ),
        (
            |b, _, v, _, _| wr_f32(b, v + 8, f32::INFINITY).unwrap(),
            FailureCode::MapNonFinite,
        ),
        (
            |b, t, _, _, _| wr_u32(b, t + 12, 2).unwrap(),
            FailureCode::MapInconsistent,
        ),
        (
            |b, _, _, _, _| wr_u32(b, 16, (MAX_MAP_VERTICES + 1) as u32).unwrap(),
            FailureCode::MapCountOutOfRange,
        ),
        (
            |b, _, _, _, _| wr_u32(b, 32, 0).unwrap(),
            FailureCode::MapCountOutOfRange,
        ),
        // Tile box shrunk so it no longer bounds its triangles.
        (
            |b, _, _, k, _| wr_f32(b, k + 12, -50.0).unwrap(),
            FailureCode::MapInconsistent,
        ),
        // Tile run does not start where the previous one ended.
        (
            |b, _, _, k, _| wr_u32(b, k + 24, 1).unwrap(),
            FailureCode::MapInconsistent,
        ),
        // A vertex outside the header bounds.
        (
            |b, _, v, _, _| wr_f32(b, v, -50.0).unwrap(),
            FailureCode::MapInconsistent,
        ),
    ];
    for (i, (edit, code)) in cases.iter().enumerate() {
        let mut b = good.clone();
        edit(&mut b, tri, vert, tiles, nv);
        if !matches!(
            code,
            FailureCode::MapBadMagic | FailureCode::MapUnsupportedVersion
        ) {
            // Without resealing, the CRC catches it first.
            assert_eq!(
                MapView::new_checked(&b).err(),
                Some(FailureCode::MapCrcMismatch),
                "case {i}"
            );
            reseal(&mut b).unwrap();
        }
        assert_eq!(MapView::new_checked(&b).err(), Some(*code), "case {i}");
    }
}

/// Verifies: VTSM-MAP-004, VTSM-MAP-008
#[test]
fn encoder_rejects_bad_sources_and_small_buffers() {
    let mesh = Mesh::grid(3, 0.5);
    let src = mesh.source(1.0);
    let need = encoded_len(&src).unwrap();
    let mut out = vec![0u8; need - 1];
    assert_eq!(
        encode(&src, &mut out),
        Err(FailureCode::MapEncodeBufferTooSmall)
    );
    assert!(out.iter().all(|b| *b == 0));

    let mut m = Mesh::grid(3, 0.5);
    m.vertices[2][1] = f32::NAN;
    assert_eq!(encoded_len(&m.source(1.0)), Err(FailureCode::MapNonFinite));
    let mut m = Mesh::grid(3, 0.5);
    m.triangles[5][2] = m.vertices.len() as u32;
    assert_eq!(
        encoded_len(&m.source(1.0)),
        Err(FailureCode::MapIndexOutOfRange)
    );
    let mut m = Mesh::grid(3, 0.5);
    m.uvs[0][1][0] = f32::NAN;
    assert_eq!(encoded_len(&m.source(1.0)), Err(FailureCode::MapNonFinite));
    let mut m = Mesh::grid(3, 0.5);
    m.mask.pop();
    assert_eq!(
        encoded_len(&m.source(1.0)),
        Err(FailureCode::MapInconsistent)
    );
    let m = Mesh::grid(3, 0.5);
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert_eq!(
            encoded_len(&m.source(bad)),
            Err(FailureCode::MapTileSizeOutOfRange),
            "{bad}"
        );
    }
    // A tile size so small that the grid exceeds MAX_MAP_TILES has its own code.
    for tiny in [1.0e-6, 1.0e-9, f32::MIN_POSITIVE] {
        assert_eq!(
            encoded_len(&m.source(tiny)),
            Err(FailureCode::MapTileSizeOutOfRange),
            "{tiny}"
        );
    }
    // encoded_len bounds the exact product length.
    let n = encode(&src, &mut vec![0u8; need]).unwrap();
    assert!(n <= need);
}

/// Verifies: VTSM-MAP-008
#[test]
fn encoder_rejects_a_mesh_of_only_degenerate_triangles() {
    let mut m = Mesh::grid(3, 0.5);
    // Collapse every triangle: all corners of each on one line (x axis) or one point.
    for (k, v) in m.vertices.iter_mut().enumerate() {
        *v = [k as f32 * 0.1, 0.0, 0.0];
    }
    assert_eq!(encoded_len(&m.source(1.0)), Err(FailureCode::MapNoSurface));
    let mut out = vec![0u8; 1 << 16];
    assert_eq!(
        encode(&m.source(1.0), &mut out),
        Err(FailureCode::MapNoSurface)
    );
    assert!(out.iter().all(|b| *b == 0));
    // One triangle with area is enough (degenerate ones are allowed among others).
    let mut m = Mesh::grid(3, 0.5);
    for t in m.triangles.iter_mut().skip(1) {
        *t = [t[0], t[0], t[1]];
    }
    assert!(encoded_len(&m.source(1.0)).is_ok());
}

/// Verifies: VTSM-MAP-008
#[test]
fn encoder_rejects_absurd_texture_coordinates() {
    for bad in [1.0e30, -1.0e30, 1.0e5] {
        let mut m = Mesh::grid(3, 0.5);
        m.uvs[4][2][1] = bad;
        assert_eq!(
            encoded_len(&m.source(1.0)),
            Err(FailureCode::MapUvOutOfRange),
            "{bad}"
        );
    }
    // Beyond the texture but within MAX_UV_PX: accepted (it samples the edge).
    let mut m = Mesh::grid(3, 0.5);
    m.uvs[4][2][1] = 100.0;
    assert!(encoded_len(&m.source(1.0)).is_ok());
}

/// Verifies: VTSM-MAP-008
#[test]
fn resealed_products_with_absurd_uvs_or_no_surface_are_rejected() {
    let good = Mesh::grid(4, 0.5).encode(1.0);
    let uv = section_off(&good, SEC_UVS);
    let vert = section_off(&good, SEC_VERTICES);
    let nv = rd_u32(&good, 16).unwrap() as usize;
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        reseal(&mut b).unwrap();
        MapView::new_checked(&b).err()
    };
    for (v, code) in [
        (1.0e30, FailureCode::MapUvOutOfRange),
        (-1.0e30, FailureCode::MapUvOutOfRange),
        (MAX_UV_PX * 2.0, FailureCode::MapUvOutOfRange),
        (f32::NAN, FailureCode::MapNonFinite),
        (f32::INFINITY, FailureCode::MapNonFinite),
        (f32::NEG_INFINITY, FailureCode::MapNonFinite),
    ] {
        for corner in [0, 5] {
            let got = edit(&|b| wr_f32(b, uv + UV_BYTES * 7 + 4 * corner, v).unwrap());
            assert_eq!(got, Some(code), "uv {v} at {corner}");
        }
    }
    assert_eq!(
        edit(&|b| wr_f32(b, uv + 4, MAX_UV_PX).unwrap()),
        None,
        "the bound itself is accepted"
    );
    // Non-finite vertices: MapNonFinite.
    for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(
            edit(&|b| wr_f32(b, vert + VERTEX_BYTES * 3 + 4, v).unwrap()),
            Some(FailureCode::MapNonFinite)
        );
    }
    // Every vertex moved onto the first one: all triangles have zero area (the
    // tiles and bounds still hold them).
    let first: [u8; VERTEX_BYTES] = good[vert..vert + VERTEX_BYTES].try_into().unwrap();
    assert_eq!(
        edit(&|b| {
            for i in 0..nv {
                b[vert + i * VERTEX_BYTES..vert + (i + 1) * VERTEX_BYTES].copy_from_slice(&first);
            }
        }),
        Some(FailureCode::MapNoSurface)
    );
}

/// The same product in the version-1 layout: no origin, header of
/// [`HEADER_LEN_V1`] bytes, sections moved up by the 24 origin bytes.
fn as_version_1(v2: &[u8]) -> Vec<u8> {
    let shift = HEADER_LEN - HEADER_LEN_V1;
    let mut b = Vec::with_capacity(v2.len() - shift);
    b.extend_from_slice(&v2[..OFF_ORIGIN]);
    b.extend_from_slice(&[0; 4]); // header CRC, resealed below
    b.extend_from_slice(&v2[HEADER_LEN..]);
    wr_u32(&mut b, 8, 1).unwrap();
    wr_u32(&mut b, 12, HEADER_LEN_V1 as u32).unwrap();
    for e in &ENTRY_OFF[..SECTIONS_V2] {
        let off = rd_u32(&b, *e).unwrap();
        wr_u32(&mut b, *e, off - shift as u32).unwrap();
    }
    reseal(&mut b).unwrap();
    b
}

/// The origin is stored as three f64 bit for bit, the local vertices as given,
/// and the header records version 2.
///
/// Verifies: VTSM-MAP-009
#[test]
fn origin_round_trips_in_f64() {
    let mesh = Mesh::grid(4, 0.5);
    let origin = [391_234.567_8, 3_784_321.987_6, 312.25];
    let src = MapSource {
        origin,
        ..mesh.source(1.0)
    };
    let mut out = vec![0u8; encoded_len(&src).unwrap()];
    let n = encode(&src, &mut out).unwrap();
    let map = MapView::new_checked(&out[..n]).unwrap();
    assert_eq!(map.origin().map(f64::to_bits), origin.map(f64::to_bits));
    assert_eq!(map.version(), VERSION);
    assert_eq!(rd_u32(&out, 8), Some(2));
    assert_eq!(rd_u32(&out, 12), Some(HEADER_LEN as u32));
    for (i, p) in mesh.vertices.iter().enumerate() {
        assert_eq!(map.vertex(i as u32).unwrap(), Vec3::new(p[0], p[1], p[2]));
    }
    // Only the origin bytes differ from the same mesh at origin 0 (and the header CRC).
    let zero = mesh.encode(1.0);
    assert_eq!(zero.len(), n);
    let differing: Vec<usize> = (0..n).filter(|&k| zero[k] != out[k]).collect();
    assert!(
        differing
            .iter()
            .all(|&k| (OFF_ORIGIN..HEADER_LEN).contains(&k)),
        "{differing:?}"
    );
}

/// A version-1 product (no origin) is still read, with origin 0 and the same
/// content as the version-2 product it was made from.
///
/// Verifies: VTSM-MAP-010
#[test]
fn version_1_product_reads_with_origin_zero() {
    let v2 = Mesh::grid(5, 0.4).encode(0.5);
    let v1 = as_version_1(&v2);
    assert_eq!(v1.len(), v2.len() - (HEADER_LEN - HEADER_LEN_V1));
    let (a, b) = (
        MapView::new_checked(&v2).unwrap(),
        MapView::new_checked(&v1).unwrap(),
    );
    assert_eq!(b.version(), 1);
    assert_eq!(b.origin(), [0.0; 3]);
    for m in [&a, &b] {
        assert!(!m.scored());
        assert_eq!(m.score_total(), 0);
        assert_eq!(m.mask_score(0), None);
        assert_eq!(m.draw_mask_index(0), None);
    }
    assert!(a.mask_vertex_count() > 0);
    for k in 0..a.mask_vertex_count() {
        assert_eq!(a.mask_vertex(k), b.mask_vertex(k));
    }
    assert_eq!(a.vertex_count(), b.vertex_count());
    for i in 0..a.vertex_count() {
        assert_eq!(a.vertex(i), b.vertex(i));
    }
    for i in 0..a.triangle_count() {
        assert_eq!(a.triangle(i), b.triangle(i));
    }
    for i in 0..a.tile_count() {
        assert_eq!(a.tile(i), b.tile(i));
    }
    assert_eq!(a.texture_bytes(), b.texture_bytes());
    // Truncations and byte flips of the old layout are caught as well.
    for len in 0..v1.len() {
        assert_eq!(
            MapView::new_checked(&v1[..len]).err(),
            Some(FailureCode::MapTruncated),
            "len {len}"
        );
    }
    for pos in 0..HEADER_LEN_V1 {
        let mut c = v1.clone();
        c[pos] ^= 0x5A;
        assert!(MapView::new_checked(&c).is_err(), "byte {pos} accepted");
    }
}

/// A non-finite or absurd origin is refused by the encoder (nothing written)
/// and by the reader, with its own code.
///
/// Verifies: VTSM-MAP-009
#[test]
fn non_finite_or_huge_origin_is_rejected() {
    let mesh = Mesh::grid(3, 0.5);
    for bad in [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [0.0, 0.0, -f64::INFINITY],
        [MAX_MAP_ORIGIN_M * 1.5, 0.0, 0.0],
    ] {
        let src = MapSource {
            origin: bad,
            ..mesh.source(1.0)
        };
        assert_eq!(encoded_len(&src), Err(FailureCode::MapOriginOutOfRange));
        let mut out = vec![0xAAu8; 1 << 16];
        assert_eq!(
            encode(&src, &mut out),
            Err(FailureCode::MapOriginOutOfRange)
        );
        assert!(out.iter().all(|&b| b == 0xAA), "encoder wrote on refusal");
        let mut b = mesh.encode(1.0);
        b[OFF_ORIGIN..OFF_ORIGIN + 24].copy_from_slice(
            &[
                bad[0].to_le_bytes(),
                bad[1].to_le_bytes(),
                bad[2].to_le_bytes(),
            ]
            .concat(),
        );
        assert_eq!(
            MapView::new_checked(&b).err(),
            Some(FailureCode::MapCrcMismatch)
        );
        reseal(&mut b).unwrap();
        assert_eq!(
            MapView::new_checked(&b).err(),
            Some(FailureCode::MapOriginOutOfRange)
        );
    }
    // The largest allowed origin is accepted.
    let src = MapSource {
        origin: [-MAX_MAP_ORIGIN_M, MAX_MAP_ORIGIN_M, 0.0],
        ..mesh.source(1.0)
    };
    assert!(encoded_len(&src).is_ok());
}

/// The same mesh with and without scores: the same header fields, the six
/// sections of version 2 the same bytes (moved by the 12 bytes of the seventh
/// table entry, same lengths and CRCs), the scores after them.
fn assert_same_content(v2: &[u8], v3: &[u8]) {
    let shift = HEADER_LEN_V3 - HEADER_LEN;
    let mc = MapView::new_checked(v2).unwrap().mask_vertex_count() as usize;
    assert_eq!(v3.len(), v2.len() + shift + mc * MASK_SCORE_BYTES);
    assert_eq!(v2[16..OFF_SECTIONS], v3[16..OFF_SECTIONS]);
    assert_eq!(
        v2[OFF_ORIGIN..OFF_ORIGIN + 24],
        v3[OFF_ORIGIN..OFF_ORIGIN + 24]
    );
    for e in &ENTRY_OFF[..SECTIONS_V2] {
        let rd = |b: &[u8], k: usize| rd_u32(b, e + 4 * k).unwrap() as usize;
        assert_eq!(rd(v3, 0), rd(v2, 0) + shift, "entry at {e}");
        assert_eq!(
            (rd(v3, 1), rd(v3, 2)),
            (rd(v2, 1), rd(v2, 2)),
            "entry at {e}"
        );
    }
    assert_eq!(
        v2[HEADER_LEN..],
        v3[HEADER_LEN_V3..v3.len() - mc * MASK_SCORE_BYTES]
    );
    let scores = section_off(v3, SEC_SCORES);
    assert_eq!(scores, v3.len() - mc * MASK_SCORE_BYTES);
    assert_eq!(
        rd_u32(v3, ENTRY_OFF[SEC_SCORES] + 4),
        Some((mc * MASK_SCORE_BYTES) as u32)
    );
}

/// A source with scores is written as version 3: scores back bit for bit in
/// mask order, the running sums' total, and every value of `r` in
/// `0..score_total()` drawing mask vertex `k` exactly `score[k]` times (a
/// zero score never); the rest of the product is the version-2 one.
///
/// Verifies: VTSM-MAP-010, VTSM-MAP-011
#[test]
fn scored_product_round_trips_and_draws_in_proportion() {
    let mesh = Mesh::grid(5, 0.4);
    let scores = mesh.scores();
    let v3 = mesh.encode_scored(0.5, &scores);
    let map = MapView::new_checked(&v3).unwrap();
    assert_eq!(map.version(), VERSION_SCORED);
    assert_eq!(rd_u32(&v3, 8), Some(3));
    assert_eq!(rd_u32(&v3, 12), Some(HEADER_LEN_V3 as u32));
    assert!(map.scored());
    let mc = map.mask_vertex_count();
    assert!(mc > 0);
    let want: Vec<u8> = (0..mc)
        .map(|k| scores[map.mask_vertex(k).unwrap() as usize])
        .collect();
    let got: Vec<u8> = (0..mc).map(|k| map.mask_score(k).unwrap()).collect();
    assert_eq!(got, want);
    assert!(want.contains(&0) && want.contains(&255), "{want:?}");
    assert_eq!(map.mask_score(mc), None);
    let total: u32 = want.iter().map(|s| u32::from(*s)).sum();
    assert_eq!(map.score_total(), total);
    let mut hits = vec![0u32; mc as usize];
    let mut last = 0;
    for r in 0..total {
        let k = map.draw_mask_index(r).unwrap();
        assert!(k >= last, "draws follow r: {r} gave {k} after {last}");
        last = k;
        hits[k as usize] += 1;
    }
    assert_eq!(hits, want.iter().map(|s| u32::from(*s)).collect::<Vec<_>>());
    for r in [total, total + 1, u32::MAX] {
        assert_eq!(map.draw_mask_index(r), None, "r {r}");
    }
    // The check's result carries the scores across detach and attach.
    let again = map.detach().attach(&v3).unwrap();
    assert_eq!(again.score_total(), total);
    assert_eq!(
        again.draw_mask_index(total - 1),
        map.draw_mask_index(total - 1)
    );
    assert_same_content(&mesh.encode(0.5), &v3);
}

/// One mask vertex scored, the rest zero: every draw is that vertex.
///
/// Verifies: VTSM-MAP-011
#[test]
fn a_single_scored_mask_vertex_takes_every_draw() {
    let mesh = Mesh::grid(4, 0.5);
    let plain = MapView::new_checked(&mesh.encode(1.0))
        .unwrap()
        .mask_vertex(3)
        .unwrap();
    let mut scores = vec![0u8; mesh.vertices.len()];
    scores[plain as usize] = 7;
    let v3 = mesh.encode_scored(1.0, &scores);
    let map = MapView::new_checked(&v3).unwrap();
    assert_eq!(map.score_total(), 7);
    for r in 0..7 {
        assert_eq!(map.draw_mask_index(r), Some(3));
    }
    assert_eq!(map.draw_mask_index(7), None);
}

/// Without scores the encoder writes version 2 exactly as before: version 2,
/// unscored, and the length of the version-2 layout.
///
/// Verifies: VTSM-MAP-010
#[test]
fn unscored_source_is_written_as_version_2() {
    let mesh = Mesh::grid(5, 0.4);
    let bytes = mesh.encode(0.5);
    let map = MapView::new_checked(&bytes).unwrap();
    assert_eq!(map.version(), VERSION);
    assert_eq!(rd_u32(&bytes, 8), Some(2));
    assert_eq!(rd_u32(&bytes, 12), Some(HEADER_LEN as u32));
    assert!(!map.scored());
    assert_eq!(map.score_total(), 0);
    assert_eq!(map.mask_score(0), None);
    assert_eq!(map.draw_mask_index(0), None);
    let (tw, th) = (map.texture().width(), map.texture().height());
    let lay = Layout::new(
        HEADER_LEN,
        map.vertex_count() as usize,
        map.triangle_count() as usize,
        map.tile_count() as usize,
        map.mask_vertex_count() as usize,
        tw,
        th,
    );
    assert_eq!(bytes.len(), lay.total);
    assert_eq!(section_off(&bytes, SEC_TILES), HEADER_LEN);
    // The header ends with its CRC where version 2 has it.
    assert_eq!(
        rd_u32(&bytes, HEADER_LEN - 4),
        Some(crc32(&bytes[..HEADER_LEN - 4]))
    );
}

/// A score section that is not a running sum of bytes is refused with its own
/// code once the CRCs are made to match: a step above 255, a decrease, a zero
/// total over mask vertices; a table entry that disagrees with the counts is
/// an inconsistency.
///
/// Verifies: VTSM-MAP-011
#[test]
fn bad_score_sections_are_rejected() {
    let mesh = Mesh::grid(4, 0.5);
    let good = mesh.encode_scored(1.0, &mesh.scores());
    let at = section_off(&good, SEC_SCORES);
    let mc = rd_u32(&good, 28).unwrap() as usize;
    assert!(mc >= 3);
    let cum = move |b: &[u8], k: usize| rd_u32(b, at + 4 * k).unwrap();
    let total = cum(&good, mc - 1);
    type Edit = Box<dyn Fn(&mut Vec<u8>)>;
    let cases: Vec<(&str, Edit, FailureCode)> = vec![
        (
            "first step 256",
            Box::new(move |b: &mut Vec<u8>| {
                for k in 0..mc {
                    let c = cum(b, k);
                    wr_u32(b, at + 4 * k, c + 256).unwrap();
                }
            }),
            FailureCode::MapBadScores,
        ),
        (
            "a later step 256",
            Box::new(move |b: &mut Vec<u8>| {
                for k in 1..mc {
                    let c = cum(b, k);
                    wr_u32(b, at + 4 * k, c + 256).unwrap();
                }
            }),
            FailureCode::MapBadScores,
        ),
        (
            "decrease",
            Box::new(move |b: &mut Vec<u8>| {
                let c = cum(b, 1);
                wr_u32(b, at, c + 1).unwrap();
            }),
            FailureCode::MapBadScores,
        ),
        (
            "last entry below the one before",
            Box::new(move |b: &mut Vec<u8>| wr_u32(b, at + 4 * (mc - 1), 0).unwrap()),
            FailureCode::MapBadScores,
        ),
        (
            "zero total",
            Box::new(move |b: &mut Vec<u8>| {
                for k in 0..mc {
                    wr_u32(b, at + 4 * k, 0).unwrap();
                }
            }),
            FailureCode::MapBadScores,
        ),
        (
            "score section length disagrees",
            Box::new(|b: &mut Vec<u8>| {
                let len = rd_u32(b, ENTRY_OFF[SEC_SCORES] + 4).unwrap();
                wr_u32(b, ENTRY_OFF[SEC_SCORES] + 4, len - 4).unwrap();
            }),
            FailureCode::MapInconsistent,
        ),
    ];
    assert!(total > 0);
    for (name, edit, code) in &cases {
        let mut b = good.clone();
        edit(&mut b);
        assert_ne!(b, good, "{name}");
        assert_eq!(
            MapView::new_checked(&b).err(),
            Some(FailureCode::MapCrcMismatch),
            "{name}: without resealing, the CRC catches it first"
        );
        reseal(&mut b).unwrap();
        assert_eq!(MapView::new_checked(&b).err(), Some(*code), "{name}");
    }
    // The largest step and a run of zero steps are accepted.
    let mut b = good.clone();
    for k in 0..mc {
        let c = if k == 0 {
            255
        } else {
            255 + u32::from(k == mc - 1)
        };
        wr_u32(&mut b, at + 4 * k, c).unwrap();
    }
    reseal(&mut b).unwrap();
    let map = MapView::new_checked(&b).unwrap();
    assert_eq!(map.score_total(), 256);
    assert_eq!(map.mask_score(0), Some(255));
    assert_eq!(map.mask_score(1), Some(0));
    assert_eq!(map.draw_mask_index(255), Some(mc as u32 - 1));
}

/// The encoder refuses scores that are not one per vertex and scores that are
/// zero on every mask vertex, writing nothing; a mesh without mask triangles
/// gets an empty score section with total 0, and draws fail.
///
/// Verifies: VTSM-MAP-011
#[test]
fn encoder_rejects_bad_scores() {
    let mesh = Mesh::grid(4, 0.5);
    let nv = mesh.vertices.len();
    for len in [0, nv - 1, nv + 1] {
        let scores = vec![1u8; len];
        let src = MapSource {
            vertex_scores: Some(&scores),
            ..mesh.source(1.0)
        };
        assert_eq!(
            encoded_len(&src),
            Err(FailureCode::MapInconsistent),
            "{len}"
        );
    }
    // Zero on every mask vertex, positive elsewhere.
    let on_mask: BTreeSet<u32> = mesh
        .triangles
        .iter()
        .zip(&mesh.mask)
        .filter(|(_, m)| **m)
        .flat_map(|(t, _)| t.iter().copied())
        .collect();
    let scores: Vec<u8> = (0..nv as u32)
        .map(|v| if on_mask.contains(&v) { 0 } else { 9 })
        .collect();
    let src = MapSource {
        vertex_scores: Some(&scores),
        ..mesh.source(1.0)
    };
    assert_eq!(encoded_len(&src), Err(FailureCode::MapBadScores));
    let mut out = vec![0xAAu8; 1 << 16];
    assert_eq!(encode(&src, &mut out), Err(FailureCode::MapBadScores));
    assert!(out.iter().all(|&b| b == 0xAA), "encoder wrote on refusal");
    // No mask triangle: version 3 with an empty score section.
    let mut m = Mesh::grid(4, 0.5);
    m.mask.iter_mut().for_each(|x| *x = false);
    let bytes = m.encode_scored(1.0, &vec![0u8; nv]);
    let map = MapView::new_checked(&bytes).unwrap();
    assert_eq!(map.version(), VERSION_SCORED);
    assert!(map.scored());
    assert_eq!((map.mask_vertex_count(), map.score_total()), (0, 0));
    assert_eq!(map.mask_score(0), None);
    assert_eq!(map.draw_mask_index(0), None);
    assert_eq!(
        bytes.len(),
        m.encode(1.0).len() + HEADER_LEN_V3 - HEADER_LEN
    );
    // encoded_len bounds the exact length with scores too.
    let scores = mesh.scores();
    let src = MapSource {
        vertex_scores: Some(&scores),
        ..mesh.source(1.0)
    };
    let need = encoded_len(&src).unwrap();
    assert!(encode(&src, &mut vec![0u8; need]).unwrap() <= need);
    assert_eq!(
        encode(&src, &mut vec![0u8; need - 1]),
        Err(FailureCode::MapEncodeBufferTooSmall)
    );
}

/// Every triangle lies in the tile `tile_at` gives for its centroid, every
/// mask vertex is found at its own index and no other vertex is, and points
/// off the grid or not finite have no tile.
///
/// Verifies: VTSM-RELOC-047
#[test]
fn tile_at_and_mask_index_of_invert_the_products_layout() {
    let mesh = Mesh::grid(9, 0.3);
    let bytes = mesh.encode(0.5);
    let map = MapView::new_checked(&bytes).unwrap();
    let (tx, ty, size) = map.tile_grid();
    assert!(
        tx > 2 && ty > 2,
        "a grid of several tiles: {tx}×{ty} of {size} m"
    );
    let mut seen = 0u32;
    for t in 0..map.tile_count() {
        let tile = map.tile(t).unwrap();
        for i in tile.first_triangle..tile.first_triangle + tile.triangle_count {
            let [a, b, c] = map.triangle_vertices(i).unwrap();
            let g = (a + b + c) / 3.0;
            assert_eq!(map.tile_at(g.x, g.y), Some(t), "triangle {i}");
            seen += 1;
        }
    }
    assert_eq!(seen, map.triangle_count());
    let (lo, hi) = map.bounds();
    for (x, y) in [
        (lo.x - 0.01, lo.y),
        (lo.x, lo.y - 0.01),
        (lo.x + size * tx as f32 + 0.01, hi.y),
        (f32::NAN, lo.y),
        (lo.x, f32::INFINITY),
    ] {
        assert_eq!(map.tile_at(x, y), None, "({x}, {y})");
    }
    let mask: BTreeSet<u32> = (0..map.mask_vertex_count())
        .map(|k| map.mask_vertex(k).unwrap())
        .collect();
    assert!(!mask.is_empty() && mask.len() < mesh.vertices.len());
    for v in 0..map.vertex_count() + 3 {
        match map.mask_index_of(v) {
            Some(k) => assert_eq!(map.mask_vertex(k), Some(v)),
            None => assert!(!mask.contains(&v), "mask vertex {v} not found"),
        }
    }
    assert_eq!(map.mask_index_of(u32::MAX), None);
}

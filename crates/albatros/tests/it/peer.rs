//! Tests of the peer's triangle file (`albatros::peer`): exact header bytes, a round
//! trip through the reader, depth order kept in clip space, and the triangle count of
//! a built-in scene's frame.

use albatros::db::builtin;
use albatros::frame::FrameList;
use albatros::gp::setup::push_flat_polygon;
use albatros::gp::{self, Database, GpConfig};
use albatros::peer::{self, DepthRange, PeerFormatError, HEADER_LEN, VERTEX_LEN};
use glam::{DVec2, Vec3};

fn empty_frame(w: u32, h: u32) -> FrameList {
    FrameList { width: w, height: h, visibility: f32::INFINITY, ..FrameList::default() }
}

fn written(frame: &FrameList) -> Vec<u8> {
    let mut bytes = Vec::new();
    peer::write_triangles(frame, &mut bytes).expect("writing to a Vec");
    bytes
}

/// A quad (two triangles) near the eye and a triangle farther away behind it.
fn two_polygons() -> FrameList {
    let mut frame = empty_frame(64, 32);
    frame.background = Vec3::new(1.0, 0.5, 0.0);
    let quad = [DVec2::new(4.0, 4.0), DVec2::new(40.0, 4.0), DVec2::new(40.0, 28.0), DVec2::new(4.0, 28.0)];
    assert!(push_flat_polygon(&mut frame, &quad, Vec3::new(0.2, 0.4, 0.6), 1.0 / 2.0));
    let tri = [DVec2::new(10.0, 2.0), DVec2::new(60.0, 16.0), DVec2::new(10.0, 30.0)];
    assert!(push_flat_polygon(&mut frame, &tri, Vec3::new(0.9, 0.1, 0.1), 1.0 / 10.0));
    frame
}

#[test]
fn header_bytes_are_exact() {
    let frame = two_polygons();
    let bytes = written(&frame);
    let expected: [u8; 32] = [
        b'S', b'G', b'S', b'C', // magic
        1, 0, 0, 0, // version
        64, 0, 0, 0, // width
        32, 0, 0, 0, // height
        4, 0, 0, 0, // msaa
        3, 0, 0, 0, // triangles: 2 + 1
        0, 0, 0, 0, // flags
        255, 128, 0, 255, // clear colour (1, 0.5, 0) as RGBA8, R in the low byte
    ];
    assert_eq!(&bytes[..HEADER_LEN], &expected);
    assert_eq!(bytes.len(), HEADER_LEN + 3 * 3 * VERTEX_LEN);
}

#[test]
fn round_trip_reads_what_was_written() {
    let frame = two_polygons();
    let bytes = written(&frame);
    let file = peer::read_triangles(&bytes).expect("a valid file");
    assert_eq!((file.width, file.height, file.msaa, file.flags), (64, 32, 4, 0));
    assert_eq!(file.clear, [255, 128, 0, 255]);
    assert_eq!(file.triangle_count(), 3);
    // The first vertex of the first fan: (4, 4) px at Z = 2, colour (0.2, 0.4, 0.6).
    let v = file.vertices[0];
    let w = 2.0;
    assert!((v.clip[3] - w).abs() < 1e-5, "{v:?}");
    assert!((v.clip[0] / w - (2.0 * 4.0 / 64.0 - 1.0)).abs() < 1e-5, "{v:?}");
    assert!((v.clip[1] / w - (1.0 - 2.0 * 4.0 / 32.0)).abs() < 1e-5, "{v:?}");
    for (c, e) in v.color.iter().zip([0.2, 0.4, 0.6]) {
        assert!((c - e).abs() < 1e-5, "{v:?}");
    }
    // Every float read back is the bit pattern written.
    for (i, v) in file.vertices.iter().enumerate() {
        let at = HEADER_LEN + i * VERTEX_LEN;
        for (k, f) in v.clip.iter().chain(&v.color).enumerate() {
            assert_eq!(f.to_le_bytes(), bytes[at + 4 * k..at + 4 * k + 4]);
        }
    }
    // Malformed input is refused, never a panic.
    assert_eq!(peer::read_triangles(&bytes[..10]), Err(PeerFormatError::TooShort(10)));
    assert!(matches!(peer::read_triangles(&bytes[..bytes.len() - 1]), Err(PeerFormatError::LengthMismatch { .. })));
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(matches!(peer::read_triangles(&bad), Err(PeerFormatError::BadMagic(_))));
    let mut bad = bytes;
    bad[4] = 2;
    assert_eq!(peer::read_triangles(&bad), Err(PeerFormatError::BadVersion(2)));
}

#[test]
fn nearer_polygon_has_smaller_depth() {
    let frame = two_polygons();
    let file = peer::read_triangles(&written(&frame)).expect("a valid file");
    let ndc = |i: usize| file.vertices[i].clip[2] / file.vertices[i].clip[3];
    // Vertices 0..6: the quad at Z = 2; 6..9: the triangle at Z = 10.
    let near = (0..6).map(ndc).fold(f32::NEG_INFINITY, f32::max);
    let far = (6..9).map(ndc).fold(f32::INFINITY, f32::min);
    assert!(near < far, "near {near} far {far}");
    for i in 0..9 {
        assert!(ndc(i) > -1.0 && ndc(i) < 1.0, "vertex {i}: {}", ndc(i));
    }
}

#[test]
fn builtin_scene_writes_a_fan_per_polygon_in_depth_order() {
    let scene = builtin::scene("default").expect("built-in");
    let db = Database::new(scene);
    let (frame, _) = gp::frame_of_scene(&db, &GpConfig::default());
    let expected: usize = frame.polygons.iter().map(|p| (p.vertices.end - p.vertices.start) as usize - 2).sum();
    assert!(expected > 1000, "{expected}");
    let bytes = written(&frame);
    let file = peer::read_triangles(&bytes).expect("a valid file");
    assert_eq!(file.triangle_count(), expected);
    assert_eq!(u32::from_le_bytes(bytes[20..24].try_into().unwrap()) as usize, expected);
    assert_eq!((file.width, file.height), (frame.width, frame.height));
    // z / w is inside (-1, 1) and never decreases as the eye-space depth w grows.
    let mut zw: Vec<(f32, f32)> = file.vertices.iter().map(|v| (v.clip[3], v.clip[2] / v.clip[3])).collect();
    assert!(zw.iter().all(|&(w, z)| w > 0.0 && z > -1.0 && z < 1.0));
    zw.sort_by(|a, b| a.0.total_cmp(&b.0));
    for pair in zw.windows(2) {
        assert!(pair[1].1 >= pair[0].1 - 1e-6, "{pair:?}");
    }
    let range = DepthRange::of_frame(&frame);
    assert!(range.near > 0.0 && range.far > range.near);
    assert!(file.vertices.iter().all(|v| v.color.iter().all(|c| (0.0..=1.0).contains(c))));
}

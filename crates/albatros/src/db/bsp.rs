//! BSP tree over the static database (SYSTEM.md 2, "Priority"): built once when the
//! scene is loaded, traversed front to back for every eye position, so that the
//! frame list comes out in exact priority order for non-intersecting geometry.
//!
//! # Building
//! A node splits space by a plane; faces that straddle it are split in two (vertex
//! position, normal and intensity interpolated), so that the total area of every face
//! is kept. Two kinds of plane are tried, the cheaper wins (cost = 8 x splits +
//! imbalance):
//! - free axis-aligned planes through a vertex coordinate near the median of the face
//!   centroids: these cut grids, terrain and cities into halves without splitting
//!   anything;
//! - the plane of one of the faces (auto-partition), which is always possible and ends
//!   the recursion: the faces lying in a node's plane are stored at that node.
//!
//! A face lying in a free plane goes to the side its normal points to: from that side
//! it can hide only what lies behind the plane.
//!
//! The builder (`Builder`) works on a copy of each face's numbers rather than on the
//! faces: the nodes still to build keep their lists of faces one after the other in
//! one array (a work stack, the next node's list at its end), each entry (`Item`)
//! carrying its face's extent along each axis, centroid and plane, so that the
//! tests of the free planes, which are most of the work, read the list in sequence
//! and two numbers a face (a face is in front of `x = d` exactly when its greatest
//! `x` is), and nothing is allocated per node. A face plane's test reads the
//! item's box first (its corners nearest and farthest along the normal bound every
//! vertex's computed distance) and computes every vertex's distance, from one array
//! of the faces' positions, only when the box straddles a border. The tree is the
//! one the plain builder made (each face's vertices read at every test, a list per
//! node), number for number: the tests check it against that builder.
//!
//! A large tree is built in parallel (on the current rayon pool, when it has
//! several threads): the top of the tree alone, down to the nodes with fewer than a
//! 32nd of the faces, each of whose subtrees is then set apart and built by a
//! builder of its own (its faces moved into it and numbered in its list's order, the
//! same `eps`), and stitched in its place: its nodes where the work stack would
//! have built them, its faces in node order. A subtree's build reads nothing but
//! its list and `eps`, and a face's number only tells it apart, so the tree is the
//! one a single build makes whatever the threads (the tests build it so on pools
//! of 1 to 3 threads, with subtrees of every size down to single faces).
//!
//! # Traversal
//! At every node the eye's side is visited first, then the node's own faces, then the
//! far side (Fuchs, Kedem and Naylor's classic order). Moving models are not in the
//! tree: each is attached, by its bounding sphere, to the deepest node whose plane
//! its sphere straddles (or to the leaf region it lies in) and emitted there as a whole
//! before that node's faces, ordered internally by its own BSP.
//!
//! Nodes are numbered depth first, so a subtree is a range of nodes and of faces:
//! [`Bsp::pieces`] cuts the order into whole subtrees that several GPs traverse
//! on their own ([`Bsp::traverse_subtree`]), and [`FaceRecord`]s keep the faces
//! the GP reads every frame in that order. Each node keeps the box around its
//! subtree's faces ([`NodeBounds`]), with which the GP passes over whole subtrees
//! outside the view volume ([`Bsp::traverse_subtree_culled`]). Where faces share
//! their vertices (a mesh, a terrain grid), the record vertices are numbered
//! ([`Bsp::record_vertex_ids_of`]): the GP reads each distinct vertex (48 bytes,
//! [`SharedVertex`]) through 4-byte numbers rather than the records' own copies
//! (`terrain`: 12 rather than 120 bytes a triangle, a distinct vertex met by
//! about six), and transforms a position once for the faces around it (by its
//! position number). The GP asks for a face's record and vertices and for a far
//! child a little before it reads them ([`Bsp::prefetch_record`]), and the walk
//! asks for all the nodes of a small subtree (at most `SMALL_SUBTREE`, 32 nodes
//! of 48 bytes) as it enters it from a larger one (`Bsp::prefetch_nodes`): its
//! end is worked out on the way down, the front child's subtree ending where the
//! back child's begins; hints that change no result.
//!
//! **Invariant**: for non-intersecting faces, a face that can hide another from the
//! eye is emitted before it.

use crate::hint::prefetch;
use glam::{DVec3, Vec3};

/// No child.
pub const NONE: u32 = u32::MAX;
/// Faces at or below which a node always uses a face plane.
const AUTO_PARTITION_AT: usize = 12;
/// Nodes with more faces than this try face planes only when no free plane makes
/// progress.
const FACE_PLANES_BELOW: usize = 64;
/// Faces sampled when estimating a plane's cost on a large node.
const COST_SAMPLE: usize = 1024;
/// Distance from a plane, relative to the scene's extent, within which a point counts
/// as on it: 1e-6 (5 mm on a 5 km airfield; f32 vertices there are exact to 0.5 mm).
const PLANE_EPS: f64 = 1e-6;
/// Cost of one split against one face of imbalance.
const SPLIT_COST: i64 = 8;
/// Faces from which the build sets subtrees apart to build them in parallel
/// ([`Builder::grow`]); fewer are built in one go.
const APART_FROM: usize = 1 << 14;
/// The top of the tree is built alone down to the nodes with fewer than
/// `1 / APART_PARTS` of the faces; each of those subtrees is built on its own.
const APART_PARTS: usize = 32;
/// [`Bsp::vertex_ids`] are kept when the record vertices are at least this many
/// times the distinct positions: a terrain's grid has each position in about six
/// triangles (and the GP transforms it once, not six times), `many`'s separate
/// triangles in one (where looking positions up would cost and save nothing).
const VERTEX_SHARING: usize = 2;
/// The walk asks for all the nodes of a subtree of at most this many at once
/// when it enters it from a larger one ([`Bsp::prefetch_nodes`]).
///
/// Why: the walk's node loads hang one on another (a node's child is known when
/// the node is read), and a near child on the back side lies far from its parent:
/// a quarter of `terrain`'s walk stood on the node's load. A subtree's nodes lie
/// together (depth-first numbering), so that a small one is a few lines (32
/// nodes: 24), asked for at once and fetched in parallel. `terrain` one thread,
/// fastest frames: GP 1.21x with 16, a further 1.15x with 32; 64 was slower
/// (0.94x against 32).
const SMALL_SUBTREE: u32 = 32;
/// The record vertices (the first ones, in node order) whose sharing decides
/// whether all are numbered.
const VERTEX_SHARING_SAMPLE: usize = 1 << 16;

/// A vertex of a BSP face (world coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BspVertex {
    /// Position.
    pub position: DVec3,
    /// Unit normal for smooth shading.
    pub normal: Vec3,
    /// The vertex's own brightness.
    pub intensity: f32,
}

/// A plane `normal . p = d`, normal of unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: DVec3,
    /// Offset.
    pub d: f64,
}

impl Plane {
    /// Signed distance of `p`.
    #[inline]
    pub fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.d
    }
}

/// A face in the tree: a convex polygon (possibly a piece of a split face).
#[derive(Clone, Debug, PartialEq)]
pub struct BspFace {
    /// Its vertices.
    pub vertices: Vec<BspVertex>,
    /// Its plane (normal points to the front).
    pub plane: Plane,
    /// Material index.
    pub material: u32,
    /// Instance it came from.
    pub instance: u32,
    /// Face of the instance's model it came from.
    pub face: u32,
}

/// A node of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct BspNode {
    /// The splitting plane.
    pub plane: Plane,
    /// Child on the front side (`NONE` if empty).
    pub front: u32,
    /// Child on the back side.
    pub back: u32,
    /// The faces lying in the plane: a range of [`Bsp::faces`] (the faces are
    /// numbered in node order).
    pub faces: std::ops::Range<u32>,
}

/// Build statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BspStats {
    /// Faces given to the builder.
    pub input_faces: usize,
    /// Faces in the tree (after splitting).
    pub faces: usize,
    /// Nodes.
    pub nodes: usize,
    /// Face splits.
    pub splits: usize,
    /// Nodes with a free axis-aligned plane.
    pub axis_nodes: usize,
    /// Greatest depth.
    pub depth: usize,
}

/// A face as the GP reads it every frame: [`BspFace`] without its own vertex
/// allocation, its vertices a range of [`Bsp::record_vertices`].
///
/// Why a second copy: the GP reads every face of the tree every frame, in the
/// traversal's order. Each [`BspFace`] keeps its vertices in a heap block of its own,
/// allocated when the face was made (in model order, or at a split), so the
/// traversal's order visits them at random addresses: on `many` (a million
/// triangles) the load of the first vertex was a cache miss per face, about a third
/// of the GP's time. The records and their vertices lie in face order, which is
/// node order (a subtree's faces are one range), so the traversal reads them nearly
/// in sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceRecord {
    /// Its plane (normal points to the front).
    pub plane: Plane,
    /// Its vertices: `record_vertices[start..end]`.
    pub start: u32,
    /// End of its vertices.
    pub end: u32,
    /// Material index.
    pub material: u32,
    /// Instance it came from.
    pub instance: u32,
    /// Face of the instance's model it came from.
    pub face: u32,
}

/// A distinct record vertex of a tree whose faces share their vertices
/// ([`Bsp::record_vertex_ids_of`]): the vertex, and a number shared by every
/// distinct vertex at its position (bit for bit), by which the GP transforms a
/// position once ([`crate::gp`]'s vertex cache).
///
/// Layout (48 bytes, 8-aligned): `vertex` (bytes 0-39: position `f64` x 3, normal
/// `f32` x 3, intensity `f32`), `position` (40-43), 4 bytes of padding.
///
/// Why: the records' vertices repeat a shared vertex once per face around it (a
/// terrain grid's about six times: 40 bytes x 3 a triangle, 15.7 MB of `terrain`'s
/// 131 k triangles), and the GP read each face's copies from memory every frame.
/// Through the numbers it reads 4 bytes a corner, and a distinct vertex once from
/// memory for the faces around it (met together in the walk, so from the cache
/// after the first). Keyed by the whole vertex, not its position alone: the faces
/// at a position may have their own normals (`city`'s boxes: 39 k positions, 102 k
/// distinct vertices), and the GP lights each with its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedVertex {
    /// The vertex.
    pub vertex: BspVertex,
    /// Its position's number (equal numbers: equal positions, bit for bit).
    pub position: u32,
}

/// The tree.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bsp {
    /// Nodes; the root is node 0 when there is one. The nodes are numbered in
    /// depth-first order (front child first): a node's subtree is the nodes
    /// `n..n + size`, and its faces one range of [`Bsp::faces`].
    pub nodes: Vec<BspNode>,
    /// Faces.
    pub faces: Vec<BspFace>,
    /// The faces as the GP reads them ([`FaceRecord`]), numbered as [`Bsp::faces`].
    pub records: Vec<FaceRecord>,
    /// The records' vertices, in face order.
    pub record_vertices: Vec<BspVertex>,
    /// Per record vertex: its number in [`Bsp::shared_vertices`] (a number shared
    /// by every record vertex equal to it bit for bit: position, normal and
    /// intensity), when the tree's faces share their positions enough to be worth
    /// it ([`VERTEX_SHARING`]), else empty ([`Bsp::record_vertex_ids_of`]).
    vertex_ids: Vec<u32>,
    /// The distinct record vertices, in order of first appearance, each with its
    /// position number ([`SharedVertex`]); empty with [`Bsp::vertex_ids`].
    shared_vertices: Vec<SharedVertex>,
    /// Build statistics.
    pub stats: BspStats,
    /// Per node: the faces of its subtree (its own and all below it).
    subtree_faces: Vec<u32>,
    /// Per node: the nodes of its subtree (itself and all below it).
    subtree_nodes: Vec<u32>,
    /// Per node: the box around its subtree's faces.
    bounds: Vec<NodeBounds>,
    eps: f64,
}

/// The axis-aligned box around the faces of a node's subtree, as its centre and
/// half extent (the GP rejects whole subtrees outside the view volume with it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeBounds {
    /// Centre.
    pub center: DVec3,
    /// Half the extent along each axis (never negative).
    pub half: DVec3,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Side {
    Front,
    Back,
    On,
    Straddle,
}

impl Bsp {
    /// Builds the tree over `faces` (each convex, planar, non-degenerate), on the
    /// current rayon pool when it has several threads and there are many faces (the
    /// same tree as on one thread, number for number: [`Bsp::build_apart`]).
    pub fn build(faces: Vec<BspFace>) -> Self {
        // On one thread building apart only moves the faces twice more.
        let parallel = faces.len() >= APART_FROM && rayon::current_num_threads() > 1;
        let apart_below = if parallel { faces.len() / APART_PARTS } else { 0 };
        Self::build_apart(faces, apart_below)
    }

    /// [`Bsp::build`], the subtrees of fewer than `apart_below` faces built on their
    /// own on the current rayon pool (none when 0): the same tree whatever
    /// `apart_below` and the pool's threads.
    fn build_apart(faces: Vec<BspFace>, apart_below: usize) -> Self {
        let input = faces.len();
        let mut builder = Builder::new(faces);
        let mut bsp = Bsp { eps: builder.eps, ..Bsp::default() };
        bsp.stats.input_faces = input;
        if builder.faces.is_empty() {
            bsp.faces = builder.faces;
            return bsp;
        }
        let items = builder.items(apart_below > 0);
        let (on, apart) = builder.grow(&mut bsp, items, apart_below);
        if apart.is_empty() {
            bsp.faces = builder.faces;
            bsp.renumber_faces(on);
        } else {
            let (places, subtrees) = builder.build_apart(apart);
            bsp.stitch(builder.faces, on, &places, subtrees);
        }
        bsp.stats.nodes = bsp.nodes.len();
        bsp.stats.faces = bsp.faces.len();
        bsp.make_records();
        bsp
    }

    /// Copies the faces into [`Bsp::records`] and [`Bsp::record_vertices`], and
    /// counts each subtree's faces.
    fn make_records(&mut self) {
        self.records = Vec::with_capacity(self.faces.len());
        self.record_vertices = Vec::with_capacity(self.faces.iter().map(|f| f.vertices.len()).sum());
        for f in &self.faces {
            let start = self.record_vertices.len() as u32;
            self.record_vertices.extend_from_slice(&f.vertices);
            self.records.push(FaceRecord {
                plane: f.plane,
                start,
                end: self.record_vertices.len() as u32,
                material: f.material,
                instance: f.instance,
                face: f.face,
            });
        }
        self.number_vertices();
        // Children come after their parent in depth-first order.
        let mut count: Vec<u32> = self.nodes.iter().map(|n| n.faces.end - n.faces.start).collect();
        let mut nodes = vec![1u32; self.nodes.len()];
        let mut boxes: Vec<(DVec3, DVec3)> = self
            .nodes
            .iter()
            .map(|n| {
                let vs = &self.record_vertices[self.records.get(n.faces.start as usize).map_or(0, |r| r.start as usize)
                    ..self.records.get(n.faces.end as usize).map_or(self.record_vertices.len(), |r| r.start as usize)];
                vs.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v.position), hi.max(v.position))
                })
            })
            .collect();
        for n in (0..self.nodes.len()).rev() {
            let node = &self.nodes[n];
            for c in [node.front, node.back] {
                if c != NONE {
                    count[n] += count[c as usize];
                    nodes[n] += nodes[c as usize];
                    let (lo, hi) = boxes[c as usize];
                    boxes[n] = (boxes[n].0.min(lo), boxes[n].1.max(hi));
                }
            }
        }
        self.subtree_faces = count;
        self.subtree_nodes = nodes;
        // An empty subtree (none is expected) gets an empty box at the origin.
        self.bounds = boxes
            .into_iter()
            .map(|(lo, hi)| {
                if lo.cmple(hi).all() {
                    NodeBounds { center: (lo + hi) * 0.5, half: (hi - lo) * 0.5 }
                } else {
                    NodeBounds::default()
                }
            })
            .collect();
    }

    /// Numbers the record vertices ([`Bsp::vertex_ids`]) and keeps the distinct
    /// ones ([`Bsp::shared_vertices`]), each with its position's number, all in
    /// order of first appearance (so the faces of a subtree, which lie together,
    /// have their numbers and distinct vertices close together), or leaves them
    /// unnumbered when few positions are shared.
    fn number_vertices(&mut self) {
        type Key = ([u64; 3], [u32; 3], u32);
        let number = |vertices: &[BspVertex]| {
            // (aHash rather than std's SipHash: the keys are our own numbers, no
            // adversary's; the numbering follows first appearance, not the hash.)
            let mut first: ahash::AHashMap<Key, u32> = ahash::AHashMap::with_capacity(vertices.len());
            let mut positions = ahash::AHashMap::new();
            let mut shared = Vec::new();
            let ids: Vec<u32> = vertices
                .iter()
                .map(|v| {
                    let position = v.position.to_array().map(f64::to_bits);
                    let key = (position, v.normal.to_array().map(f32::to_bits), v.intensity.to_bits());
                    *first.entry(key).or_insert_with(|| {
                        let next = positions.len() as u32;
                        let position = *positions.entry(position).or_insert(next);
                        shared.push(SharedVertex { vertex: *v, position });
                        shared.len() as u32 - 1
                    })
                })
                .collect();
            (positions.len() * VERTEX_SHARING <= vertices.len()).then_some((ids, shared))
        };
        // The first faces tell: `many`'s three million separate vertices are not
        // all hashed (0.8 s of its load) to find that none is shared.
        let sample = &self.record_vertices[..self.record_vertices.len().min(VERTEX_SHARING_SAMPLE)];
        (self.vertex_ids, self.shared_vertices) =
            if number(sample).is_some() { number(&self.record_vertices) } else { None }.unwrap_or_default();
    }

    /// The vertices of a face's record.
    #[inline]
    pub fn record_vertices_of(&self, r: &FaceRecord) -> &[BspVertex] {
        &self.record_vertices[r.start as usize..r.end as usize]
    }

    /// Asks the processor to fetch face `i`'s record into the cache (a hint: no
    /// effect on any result).
    ///
    /// Why: the traversal meets the records in its own order, which jumps in
    /// memory wherever the eye sees a node from behind; the GP names a face a few
    /// visits before it reads it ([`crate::gp`]'s visits ahead), so that its
    /// record's miss overlaps the faces before it rather than stalling the face.
    #[inline(always)]
    pub fn prefetch_record(&self, i: u32) {
        // (A number out of range would only waste the hints: no check.)
        let p = self.records.as_ptr().wrapping_add(i as usize).cast::<u8>();
        // A record (56 bytes) may straddle two lines.
        prefetch(p);
        prefetch(p.wrapping_add(std::mem::size_of::<FaceRecord>() - 1));
    }

    /// [`Bsp::prefetch_record`] for face `i`'s vertices: their first and last bytes
    /// (a triangle's three vertices, 120 bytes, lie in two or three lines), or,
    /// where the tree numbers them, their numbers (the distinct vertices they
    /// name are met by the faces around them: asking for them too, a third visit
    /// ahead, measured no faster). Reads the record
    /// (best after [`Bsp::prefetch_record`]).
    #[inline(always)]
    pub fn prefetch_record_vertices(&self, i: u32) {
        if let Some(r) = self.records.get(i as usize) {
            // (Addresses out of range would only waste the hints: no checks.)
            let (start, end) = (r.start as usize, r.end as usize);
            if !self.vertex_ids.is_empty() {
                let first = self.vertex_ids.as_ptr().wrapping_add(start).cast::<u8>();
                prefetch(first);
                prefetch(self.vertex_ids.as_ptr().wrapping_add(end).cast::<u8>().wrapping_sub(1));
                return;
            }
            let first = self.record_vertices.as_ptr().wrapping_add(start).cast::<u8>();
            let last = self.record_vertices.as_ptr().wrapping_add(end).cast::<u8>().wrapping_sub(1);
            prefetch(first);
            prefetch(first.wrapping_add(64));
            prefetch(last);
        }
    }

    /// [`Bsp::prefetch_record`] for the nodes `start..end` (a small subtree's) and
    /// their subtree face counts.
    #[inline(always)]
    fn prefetch_nodes(&self, start: u32, end: u32) {
        if end <= start {
            return;
        }
        let size = std::mem::size_of::<BspNode>();
        let first = self.nodes.as_ptr().wrapping_add(start as usize).cast::<u8>();
        let bytes = (end - start) as usize * size;
        // (Addresses out of range would only waste the hints: no checks.)
        let mut k = 0;
        while k < bytes {
            prefetch(first.wrapping_add(k));
            k += 64;
        }
        prefetch(first.wrapping_add(bytes - 1));
        let counts = self.subtree_faces.as_ptr().wrapping_add(start as usize).cast::<u8>();
        prefetch(counts);
        prefetch(counts.wrapping_add((end - start) as usize * 4 - 1));
    }

    /// [`Bsp::prefetch_record`] for node `n` and its subtree's face count (which
    /// the GP's cull test reads on entering it).
    #[inline(always)]
    fn prefetch_node(&self, n: u32) {
        if let (Some(node), Some(count)) = (self.nodes.get(n as usize), self.subtree_faces.get(n as usize)) {
            let p = std::ptr::from_ref(node).cast::<u8>();
            // A node (48 bytes) may straddle two lines.
            prefetch(p);
            prefetch(p.wrapping_add(std::mem::size_of::<BspNode>() - 1));
            prefetch(std::ptr::from_ref(count).cast::<u8>());
        }
    }

    /// The numbers of a face's record vertices in [`Bsp::shared_vertex`] (equal
    /// numbers: equal vertices, bit for bit; in one tree), or `None` when the
    /// tree's faces share too few positions for them to be kept
    /// (`VERTEX_SHARING`). The GP reads a shared vertex through them, and
    /// transforms a shared position once ([`crate::gp`]'s vertex cache, by
    /// [`SharedVertex::position`]).
    #[inline]
    pub fn record_vertex_ids_of(&self, r: &FaceRecord) -> Option<&[u32]> {
        self.vertex_ids.get(r.start as usize..r.end as usize)
    }

    /// The distinct vertex numbered `id` ([`Bsp::record_vertex_ids_of`]).
    #[inline(always)]
    pub fn shared_vertex(&self, id: u32) -> &SharedVertex {
        &self.shared_vertices[id as usize]
    }

    /// The faces in the subtree of `node` (its own and all below it).
    pub fn subtree_faces(&self, node: u32) -> u32 {
        self.subtree_faces[node as usize]
    }

    /// The nodes in the subtree of `node`: `node..node + subtree_nodes(node)`.
    pub fn subtree_nodes(&self, node: u32) -> u32 {
        self.subtree_nodes[node as usize]
    }

    /// The box around the faces of the subtree of `node`.
    pub fn bounds(&self, node: u32) -> &NodeBounds {
        &self.bounds[node as usize]
    }

    /// The faces of the subtree of `node`: one range of [`Bsp::faces`] (and of
    /// [`Bsp::records`]), the faces being numbered in node order.
    pub fn subtree_face_range(&self, node: u32) -> std::ops::Range<u32> {
        let start = self.nodes[node as usize].faces.start;
        start..start + self.subtree_faces[node as usize]
    }

    /// Numbers the faces in node order, so that each node's faces are a range and the
    /// faces of nearby nodes lie together in memory for the traversal and the GP (a
    /// pure renumbering: the tree and its order are unchanged). A face that no node
    /// holds (none is expected) keeps a place after the others. On entry each
    /// node's `faces` is its range of `on` ([`Builder::grow`]).
    fn renumber_faces(&mut self, on: Vec<u32>) {
        let mut old: Vec<Option<BspFace>> = std::mem::take(&mut self.faces).into_iter().map(Some).collect();
        let mut faces = Vec::with_capacity(old.len());
        for node in &mut self.nodes {
            let start = faces.len() as u32;
            let list = &on[node.faces.start as usize..node.faces.end as usize];
            faces.extend(list.iter().filter_map(|&f| old[f as usize].take()));
            node.faces = start..faces.len() as u32;
        }
        faces.extend(old.into_iter().flatten());
        self.faces = faces;
    }

    /// Puts the subtrees built apart in their places ([`Builder::build_apart`]):
    /// the top's nodes (`self.nodes`, each set-apart subtree a placeholder node at
    /// `places`, its depth with it) and each subtree's nodes, in depth-first order,
    /// and their faces in node order ([`Bsp::renumber_faces`]), the top's from
    /// `faces` (numbered as `on`). The same tree, number for number, as one build:
    /// a subtree's nodes follow its place in the work stack's order, and every face
    /// is where its node and its place in the node's list put it.
    fn stitch(&mut self, mut faces: Vec<BspFace>, on: Vec<u32>, places: &[(u32, usize)], subtrees: Vec<Bsp>) {
        let top = std::mem::take(&mut self.nodes);
        let total: usize = subtrees.iter().map(|s| s.nodes.len()).sum::<usize>() + top.len();
        let mut nodes = Vec::with_capacity(total);
        let mut out = Vec::with_capacity(on.len() + subtrees.iter().map(|s| s.faces.len()).sum::<usize>());
        // Each top node's number in the whole tree.
        let mut number = Vec::with_capacity(top.len());
        let mut subtrees = places.iter().zip(subtrees).peekable();
        for (i, mut node) in top.into_iter().enumerate() {
            number.push(nodes.len() as u32);
            if let Some(((_, depth), sub)) = subtrees.next_if(|((place, _), _)| *place as usize == i) {
                let (first, start) = (nodes.len() as u32, out.len() as u32);
                nodes.extend(sub.nodes.into_iter().map(|mut n| {
                    for child in [&mut n.front, &mut n.back] {
                        if *child != NONE {
                            *child += first;
                        }
                    }
                    n.faces = n.faces.start + start..n.faces.end + start;
                    n
                }));
                out.extend(sub.faces);
                self.stats.splits += sub.stats.splits;
                self.stats.axis_nodes += sub.stats.axis_nodes;
                self.stats.depth = self.stats.depth.max(depth - 1 + sub.stats.depth);
            } else {
                let start = out.len() as u32;
                for &f in &on[node.faces.start as usize..node.faces.end as usize] {
                    let f = &mut faces[f as usize];
                    out.push(BspFace { vertices: std::mem::take(&mut f.vertices), ..*f });
                }
                node.faces = start..out.len() as u32;
                nodes.push(node);
            }
        }
        // The top's links, to their children's numbers.
        let mut places = places.iter().peekable();
        for (i, &n) in number.iter().enumerate() {
            if places.next_if(|(place, _)| *place as usize == i).is_some() {
                continue;
            }
            let node = &mut nodes[n as usize];
            for child in [&mut node.front, &mut node.back] {
                if *child != NONE {
                    *child = number[*child as usize];
                }
            }
        }
        self.nodes = nodes;
        self.faces = out;
    }
}

/// A node's plane as [`Builder::choose_plane`] picks it.
#[derive(Clone, Copy, Debug)]
enum Cut {
    /// A free axis-aligned plane (`normal` the unit vector of `axis`).
    Free { plane: Plane, axis: usize },
    /// The plane of face `owner`.
    Face { plane: Plane, owner: u32 },
}

impl Cut {
    fn plane(&self) -> Plane {
        match *self {
            Cut::Free { plane, .. } | Cut::Face { plane, .. } => plane,
        }
    }
}

/// A face in a node's list while the tree is built: its number in
/// [`Builder::faces`] and the numbers of it that the free planes' tests read.
///
/// Why a copy in the list: a node tries up to 9 free planes over a sample of up to
/// [`COST_SAMPLE`] faces, then sorts all its faces. The faces of a node are scattered
/// over the whole face array (after a few splits of a million random triangles,
/// anything goes), so reading each face's vertices from its own heap block (or
/// anything indexed by face) was a cache miss per face per test: on `many`, a
/// million triangles, 13 s of its start. The lists carry what the tests read and are
/// read in sequence.
///
/// A free plane `normal = e_axis` gives each vertex the distance `p[axis] - d`
/// exactly (the dot product is `p.x * n.x + p.y * n.y + p.z * n.z`, no fused
/// multiply-add, the zero terms adding only a signed zero), and `p - d` is monotone
/// in `p`: a face has a vertex more than `eps` in front of the plane exactly when its
/// greatest coordinate does, and one behind exactly when its least does. So a free
/// plane's test reads two numbers of the item ([`Builder::free_side`]).
#[derive(Clone, Copy, Debug)]
struct Item {
    /// Per axis: the least and greatest vertex coordinate ([`extent`]).
    extents: [[f64; 2]; 3],
    /// The centroid ([`centroid`]).
    centroid: [f64; 3],
    /// The face's plane (a candidate of a small node's, and the side a face lying
    /// in a free plane goes to).
    plane: Plane,
    /// The face: an index into [`Builder::faces`].
    face: u32,
}

/// The centroid of a face's vertices.
fn centroid(vs: &[BspVertex]) -> DVec3 {
    vs.iter().map(|v| v.position).sum::<DVec3>() / vs.len() as f64
}

/// The least and greatest coordinate along `axis` of a face's vertices (of equal
/// ones, the first: strict comparisons in vertex order).
fn extent(vs: &[BspVertex], axis: usize) -> [f64; 2] {
    let first = vs[0].position[axis];
    let (mut lo, mut hi) = (first, first);
    for v in &vs[1..] {
        let x = v.position[axis];
        if x < lo {
            lo = x;
        }
        if x > hi {
            hi = x;
        }
    }
    [lo, hi]
}

impl Item {
    /// The item of face number `face`.
    fn of(face: u32, f: &BspFace) -> Self {
        let vs = &f.vertices;
        Item {
            extents: std::array::from_fn(|axis| extent(vs, axis)),
            centroid: centroid(vs).to_array(),
            plane: f.plane,
            face,
        }
    }
}

/// The tree's builder: the faces (split ones included) and their vertex positions
/// in one array, in face order (a face plane's test computes every vertex's distance
/// as [`Plane::distance`] does, from [`Builder::positions`]).
///
/// **Invariant**: for every face `f`, `positions[spans[f]]` are the positions of
/// `faces[f].vertices`, and every [`Item`] of face `f` is `Item::of(f, &faces[f])`
/// (both kept so at every split).
struct Builder {
    /// The faces; a split's front piece replaces its face, the back piece is appended.
    faces: Vec<BspFace>,
    /// Per face: its vertices' positions, `positions[start..end]`.
    spans: Vec<[u32; 2]>,
    /// The faces' vertex positions.
    positions: Vec<DVec3>,
    /// [`Bsp::eps`].
    eps: f64,
}

impl Builder {
    /// Takes the faces and copies their positions; `eps` from the scene's extent.
    fn new(faces: Vec<BspFace>) -> Self {
        let vertices: usize = faces.iter().map(|f| f.vertices.len()).sum();
        let mut spans = Vec::with_capacity(faces.len());
        let mut positions = Vec::with_capacity(vertices);
        let mut extent = 1.0f64;
        for f in &faces {
            let start = positions.len() as u32;
            for v in &f.vertices {
                extent = extent.max(v.position.abs().max_element());
                positions.push(v.position);
            }
            spans.push([start, positions.len() as u32]);
        }
        Builder { faces, spans, positions, eps: extent * PLANE_EPS }
    }

    /// Every face's item, in face order (on the current rayon pool when `parallel`).
    fn items(&self, parallel: bool) -> Vec<Item> {
        let item = |(fi, f): (usize, &BspFace)| Item::of(fi as u32, f);
        if parallel {
            use rayon::prelude::*;
            self.faces.par_iter().enumerate().map(item).collect()
        } else {
            self.faces.iter().enumerate().map(item).collect()
        }
    }

    /// Builds each subtree [`Builder::grow`] set apart with a builder of its own (its
    /// faces moved out of this one's, numbered in its list's order; the same `eps`),
    /// in parallel on the current rayon pool. Returns each one's place and depth
    /// and the subtree, its faces numbered in node order ([`Bsp::renumber_faces`]).
    ///
    /// A subtree built apart is the one a single build makes: it is built from its
    /// list as the work stack holds it when its root comes to the top, by the same
    /// steps (nothing in a node's build depends on anything outside its list but
    /// `eps`), and its faces' numbers only tell them apart (a face plane's owner; a
    /// split's pieces, whose new numbers change no order: [`Bsp::renumber_faces`]).
    fn build_apart(&mut self, apart: Vec<Apart>) -> (Vec<(u32, usize)>, Vec<Bsp>) {
        use rayon::prelude::*;
        let places = apart.iter().map(|a| (a.place, a.depth)).collect();
        // The faces move out one subtree after the other; each subtree's builder then
        // copies their positions from this one's (which it only reads).
        let jobs: Vec<(Vec<BspFace>, Vec<Item>)> = apart
            .into_iter()
            .map(|Apart { items, .. }| {
                let faces = items
                    .iter()
                    .map(|item| {
                        let f = &mut self.faces[item.face as usize];
                        BspFace { vertices: std::mem::take(&mut f.vertices), ..*f }
                    })
                    .collect();
                (faces, items)
            })
            .collect();
        let (spans, positions, eps) = (&self.spans, &self.positions, self.eps);
        let subtrees = jobs
            .into_par_iter()
            .map(|(faces, mut items)| {
                let mut builder = Builder {
                    spans: Vec::with_capacity(items.len()),
                    positions: Vec::with_capacity(faces.iter().map(|f| f.vertices.len()).sum()),
                    faces,
                    eps,
                };
                for (k, item) in items.iter_mut().enumerate() {
                    let [start, end] = spans[item.face as usize];
                    let at = builder.positions.len() as u32;
                    builder.positions.extend_from_slice(&positions[start as usize..end as usize]);
                    builder.spans.push([at, builder.positions.len() as u32]);
                    item.face = k as u32;
                }
                let mut bsp = Bsp { eps, ..Bsp::default() };
                let (on, _) = builder.grow(&mut bsp, items, 0);
                bsp.faces = builder.faces;
                bsp.renumber_faces(on);
                bsp
            })
            .collect();
        (places, subtrees)
    }

    /// Builds the nodes of `items`' faces (all of them, in face order) into `bsp`
    /// (depth first, front child first) and returns the faces lying in the nodes'
    /// planes, node after node (numbered as in [`Builder::faces`]); each node's
    /// `faces` is, until [`Bsp::renumber_faces`], its range of that list.
    ///
    /// The lists of the nodes still to build lie one after the other in one array,
    /// in the order of the work stack: the top's list, the next node to build, is
    /// the array's end. A node's list is sorted in place into its back child's list
    /// and, after it, its front child's (the top, built first), so that building
    /// allocates nothing per node (on `many`, the million lists' allocations and
    /// fresh pages were a second).
    ///
    /// A node whose list has fewer than `apart_below` faces is not built: its list
    /// is set apart ([`Apart`]), with a placeholder node in its place, for
    /// [`Builder::build_apart`].
    fn grow(&mut self, bsp: &mut Bsp, mut items: Vec<Item>, apart_below: usize) -> (Vec<u32>, Vec<Apart>) {
        // Work stack of nodes to build.
        struct Work {
            /// The parent and whether this is its front child.
            link: Option<(u32, bool)>,
            /// Where the faces in this node's region start in `items` (they end
            /// where the next work's start, the top's at the end).
            start: usize,
            depth: usize,
        }
        let mut on: Vec<u32> = Vec::new();
        let mut apart = Vec::new();
        let mut stack = vec![Work { link: None, start: 0, depth: 1 }];
        let mut scratch = Scratch::default();
        while let Some(Work { link, start, depth }) = stack.pop() {
            let node = bsp.nodes.len() as u32;
            if let Some((parent, front)) = link {
                let p = &mut bsp.nodes[parent as usize];
                if front {
                    p.front = node;
                } else {
                    p.back = node;
                }
            }
            bsp.stats.depth = bsp.stats.depth.max(depth);
            if items.len() - start < apart_below {
                let at = on.len() as u32;
                bsp.nodes.push(BspNode {
                    plane: Plane { normal: DVec3::ZERO, d: 0.0 },
                    front: NONE,
                    back: NONE,
                    faces: at..at,
                });
                apart.push(Apart { place: node, depth, items: items.split_off(start) });
                continue;
            }
            let list = &items[start..];
            let mut cut = self.choose_plane(list, false, &mut scratch);
            if let Cut::Free { plane, axis } = cut {
                if !self.separates(list, axis, &plane) {
                    // The sample promised progress the whole list does not give.
                    cut = self.choose_plane(list, true, &mut scratch);
                }
            }
            let plane = cut.plane();
            let on_start = on.len() as u32;
            // The back list is written over the node's own from its start (at most
            // one back face per face read), the front list set aside.
            let front = &mut scratch.front;
            front.clear();
            let mut back = start;
            for r in start..items.len() {
                let item = items[r];
                let side = match cut {
                    Cut::Free { axis, .. } => self.free_side(&item, axis, &plane),
                    // The face whose plane this is lies in it, whatever rounding says.
                    Cut::Face { owner, .. } if item.face == owner => Side::On,
                    Cut::Face { .. } => self.item_side(&item, &plane),
                };
                let (f, b) = match side {
                    Side::Front => (Some(item), None),
                    Side::Back => (None, Some(item)),
                    Side::On => {
                        on.push(item.face);
                        (None, None)
                    }
                    Side::Straddle => {
                        bsp.stats.splits += 1;
                        self.split(item.face, &plane)
                    }
                };
                front.extend(f);
                if let Some(b) = b {
                    items[back] = b;
                    back += 1;
                }
            }
            items.truncate(back);
            items.extend_from_slice(front);
            if matches!(cut, Cut::Free { .. }) {
                bsp.stats.axis_nodes += 1;
            }
            bsp.nodes.push(BspNode { plane, front: NONE, back: NONE, faces: on_start..on.len() as u32 });
            if back > start {
                stack.push(Work { link: Some((node, false)), start, depth: depth + 1 });
            }
            if items.len() > back {
                stack.push(Work { link: Some((node, true)), start: back, depth: depth + 1 });
            }
        }
        (on, apart)
    }

    /// Which side of a face plane face `fi` lies on: every vertex's distance.
    #[inline]
    fn side(&self, fi: u32, plane: &Plane) -> Side {
        let [start, end] = self.spans[fi as usize];
        let (mut f, mut b) = (false, false);
        for &p in &self.positions[start as usize..end as usize] {
            let d = plane.distance(p);
            if d > self.eps {
                f = true;
            } else if d < -self.eps {
                b = true;
            }
        }
        match (f, b) {
            (true, true) => Side::Straddle,
            (true, false) => Side::Front,
            (false, true) => Side::Back,
            (false, false) => Side::On,
        }
    }

    /// Which side of a face plane an item's face lies on: [`Builder::side`], from
    /// the item's box when the box decides it (the same answer: see below), else
    /// from every vertex.
    ///
    /// The box's corner farthest along the normal (each coordinate the extent's end
    /// the normal's component points to) has a computed distance at least every
    /// vertex's, and the nearest corner one at most: a term `n_i * p_i` rounds
    /// monotonically in `p_i` (up for `n_i >= 0`, down otherwise), the sums and `- d`
    /// round monotonically in each term (no fused multiply-add in this build), and
    /// every vertex coordinate lies in its extent. Coordinates come from `f32` and
    /// normals are unit, so no term overflows. So a nearest corner beyond `eps` in
    /// front puts every vertex there ([`Side::Front`]), a farthest one beyond `eps`
    /// behind puts every vertex behind ([`Side::Back`]), and both within `eps` put
    /// every vertex within ([`Side::On`]).
    #[inline]
    fn item_side(&self, item: &Item, plane: &Plane) -> Side {
        self.box_side(item, plane).unwrap_or_else(|| self.side(item.face, plane))
    }

    /// [`Builder::item_side`]'s answer from the item's box alone, `None` when the
    /// box straddles `eps` on a side.
    #[inline]
    fn box_side(&self, item: &Item, plane: &Plane) -> Option<Side> {
        let n = plane.normal.to_array();
        let far = DVec3::from_array(std::array::from_fn(|axis| item.extents[axis][usize::from(n[axis] >= 0.0)]));
        let near = DVec3::from_array(std::array::from_fn(|axis| item.extents[axis][usize::from(n[axis] < 0.0)]));
        let (most, least) = (plane.distance(far), plane.distance(near));
        if least > self.eps {
            Some(Side::Front)
        } else if most < -self.eps {
            Some(Side::Back)
        } else if most <= self.eps && least >= -self.eps {
            Some(Side::On)
        } else {
            None
        }
    }

    /// The side of a free plane along `axis` a face goes to: [`Builder::side`] from
    /// the face's extent (the same answer: see [`Item`]), except that a face lying
    /// in the plane goes where its normal points (never [`Side::On`]: from that side
    /// it can hide only what lies behind the plane).
    #[inline]
    fn free_side(&self, item: &Item, axis: usize, plane: &Plane) -> Side {
        let [lo, hi] = item.extents[axis];
        match (hi - plane.d > self.eps, lo - plane.d < -self.eps) {
            (true, true) => Side::Straddle,
            (true, false) => Side::Front,
            (false, true) => Side::Back,
            (false, false) if item.plane.normal.dot(plane.normal) >= 0.0 => Side::Front,
            (false, false) => Side::Back,
        }
    }

    /// Whether a free plane leaves faces on both sides (or cuts one), so that the
    /// recursion makes progress.
    fn separates(&self, list: &[Item], axis: usize, plane: &Plane) -> bool {
        let (mut f, mut b) = (false, false);
        for item in list {
            match self.free_side(item, axis, plane) {
                Side::Straddle => return true,
                Side::Front => f = true,
                // (`free_side` never answers `On`.)
                Side::Back | Side::On => b = true,
            }
            if f && b {
                return true;
            }
        }
        false
    }

    /// Picks the plane for a node; only face planes when `faces_only`.
    fn choose_plane(&self, list: &[Item], faces_only: bool, scratch: &mut Scratch) -> Cut {
        let step = (list.len() / COST_SAMPLE).max(1);
        let sample: &[Item] = if step == 1 {
            list
        } else {
            scratch.sample.clear();
            scratch.sample.extend(list.iter().step_by(step));
            &scratch.sample
        };
        let mut best: Option<(i64, Cut)> = None;
        let consider = |cost: i64, cut: Cut, best: &mut Option<(i64, Cut)>| {
            if best.as_ref().is_none_or(|b| cost < b.0) {
                *best = Some((cost, cut));
            }
        };
        if list.len() > AUTO_PARTITION_AT && !faces_only {
            for axis in 0..3 {
                let cents = &mut scratch.centroids;
                cents.clear();
                cents.extend(sample.iter().map(|item| item.centroid[axis]));
                let mid = cents.len() / 2;
                let (_, &mut median, _) = cents.select_nth_unstable_by(mid, f64::total_cmp);
                let (below, above) = self.nearest_coordinates(sample, axis, median);
                for pos in [median, below, above] {
                    if !pos.is_finite() || pos == f64::MIN || pos == f64::MAX {
                        continue;
                    }
                    let mut normal = DVec3::ZERO;
                    normal[axis] = 1.0;
                    let plane = Plane { normal, d: pos };
                    if let Some(cost) = self.free_cost(sample, axis, &plane) {
                        consider(cost, Cut::Free { plane, axis }, &mut best);
                    }
                }
            }
        }
        // On a large node a free plane is taken when there is one: face planes are
        // for the small nodes (and for when no free plane makes progress).
        if let Some((_, cut @ Cut::Free { .. })) = best {
            if list.len() > FACE_PLANES_BELOW {
                return cut;
            }
        }
        // Face planes of a few spread-out faces.
        let candidates = 8.min(list.len());
        for k in 0..candidates {
            let owner = list[k * list.len() / candidates].face;
            let plane = list[k * list.len() / candidates].plane;
            let cost = self.face_cost(sample, &plane);
            consider(cost, Cut::Face { plane, owner }, &mut best);
        }
        best.expect("a node has at least one face").1
    }

    /// The vertex coordinates along `axis` of the sample's faces nearest `median` at
    /// or below it and at or above it (`f64::MIN`, `f64::MAX` when there is none;
    /// of equal ones the first met, face by face, vertex by vertex). A face wholly
    /// on one side gives its extent's end (the first of its equal vertices too).
    fn nearest_coordinates(&self, sample: &[Item], axis: usize, median: f64) -> (f64, f64) {
        let (mut below, mut above) = (f64::MIN, f64::MAX);
        for item in sample {
            let [lo, hi] = item.extents[axis];
            if hi < median {
                if hi > below {
                    below = hi;
                }
            } else if lo > median {
                if lo < above {
                    above = lo;
                }
            } else {
                let [start, end] = self.spans[item.face as usize];
                for p in &self.positions[start as usize..end as usize] {
                    let c = p[axis];
                    if c <= median && c > below {
                        below = c;
                    }
                    if c >= median && c < above {
                        above = c;
                    }
                }
            }
        }
        (below, above)
    }

    /// Cost of a free plane over a sample of faces; `None` if it leaves one side
    /// empty (it would not make progress).
    fn free_cost(&self, sample: &[Item], axis: usize, plane: &Plane) -> Option<i64> {
        let (mut f, mut b, mut s) = (0i64, 0i64, 0i64);
        for item in sample {
            match self.free_side(item, axis, plane) {
                Side::Front => f += 1,
                // (`free_side` never answers `On`.)
                Side::Back | Side::On => b += 1,
                Side::Straddle => s += 1,
            }
        }
        if f + s == 0 || b + s == 0 {
            return None;
        }
        Some(s * SPLIT_COST + (f - b).abs())
    }

    /// Cost of a face plane over a sample of faces (those lying in it cost nothing).
    fn face_cost(&self, sample: &[Item], plane: &Plane) -> i64 {
        let (mut f, mut b, mut s) = (0i64, 0i64, 0i64);
        for item in sample {
            match self.item_side(item, plane) {
                Side::Front => f += 1,
                Side::Back => b += 1,
                Side::Straddle => s += 1,
                Side::On => {}
            }
        }
        s * SPLIT_COST + (f - b).abs()
    }

    /// Splits face `fi` by `plane`: the front piece replaces it, the back piece is
    /// appended. Returns the pieces' items (a sliver below rounding could vanish;
    /// none does, as a straddling face has a vertex beyond `eps` on either side).
    fn split(&mut self, fi: u32, plane: &Plane) -> (Option<Item>, Option<Item>) {
        let (fv, bv) = split_polygon(&self.faces[fi as usize].vertices, plane, self.eps);
        let mut out = (None, None);
        let mut front_used = false;
        for (verts, is_front) in [(fv, true), (bv, false)] {
            if verts.len() < 3 {
                continue;
            }
            let idx = if !front_used {
                front_used = true;
                let [start, end] = self.spans[fi as usize];
                if verts.len() == (end - start) as usize {
                    // As many vertices: their positions in place.
                    for (p, v) in self.positions[start as usize..end as usize].iter_mut().zip(&verts) {
                        *p = v.position;
                    }
                } else {
                    let start = self.positions.len() as u32;
                    self.positions.extend(verts.iter().map(|v| v.position));
                    self.spans[fi as usize] = [start, self.positions.len() as u32];
                }
                self.faces[fi as usize].vertices = verts;
                fi
            } else {
                let start = self.positions.len() as u32;
                self.positions.extend(verts.iter().map(|v| v.position));
                self.spans.push([start, self.positions.len() as u32]);
                self.faces.push(BspFace { vertices: verts, ..self.faces[fi as usize] });
                (self.faces.len() - 1) as u32
            };
            let item = Some(Item::of(idx, &self.faces[idx as usize]));
            if is_front {
                out.0 = item;
            } else {
                out.1 = item;
            }
        }
        out
    }
}

/// A subtree [`Builder::grow`] leaves to be built on its own.
struct Apart {
    /// Its placeholder node.
    place: u32,
    /// Its root's depth.
    depth: usize,
    /// Its root's list.
    items: Vec<Item>,
}

/// [`Builder`]'s working space, kept from node to node.
#[derive(Default)]
struct Scratch {
    sample: Vec<Item>,
    centroids: Vec<f64>,
    /// A node's front list while it is sorted.
    front: Vec<Item>,
}

impl Bsp {
    /// Front-to-back order of the tree's faces for an eye at `eye`: `visit` is called
    /// with [`Visit::Face`] for every face, and with [`Visit::Guests`] at the place
    /// where the moving models attached to `(node, slot)` go (see [`Bsp::attach`]).
    pub fn traverse(&self, eye: DVec3, mut visit: impl FnMut(Visit)) {
        if self.nodes.is_empty() {
            visit(Visit::Guests(NONE, Slot::Straddle));
            return;
        }
        self.walk(
            0,
            eye,
            true,
            |_| None,
            |p| {
                if let Piece::Visit(v) = p {
                    visit(v)
                }
            },
        );
    }

    /// The front-to-back order of the subtree of `node` alone: the same visits that
    /// [`Bsp::traverse`] makes between entering and leaving that node.
    pub fn traverse_subtree(&self, node: u32, eye: DVec3, visit: impl FnMut(Visit)) {
        self.traverse_subtree_culled(node, eye, true, |_| false, visit);
    }

    /// [`Bsp::traverse_subtree`], except that a node for which `cull` is true is
    /// visited whole as one [`Visit::Culled`] in place of its subtree's visits, and
    /// that the guests' places are visited only with `guests` (a frame with none
    /// attached need not visit two or three places per node).
    #[inline(always)]
    pub fn traverse_subtree_culled(
        &self,
        node: u32,
        eye: DVec3,
        guests: bool,
        cull: impl Fn(u32) -> bool,
        mut visit: impl FnMut(Visit),
    ) {
        self.walk(
            node,
            eye,
            guests,
            #[inline(always)]
            |n| cull(n).then_some(Piece::Visit(Visit::Culled(n))),
            // Inlined (and so compiled with the target features of a caller that
            // has them, which a closure left out of line would not be).
            #[inline(always)]
            |p| {
                if let Piece::Visit(v) = p {
                    visit(v)
                }
            },
        );
    }

    /// The front-to-back order cut into pieces for several workers: every subtree
    /// below the root with at most `max_faces` faces comes as one
    /// [`Piece::Subtree`] (to be traversed by [`Bsp::traverse_subtree`]), the rest
    /// as single visits. Traversing the subtrees in place gives [`Bsp::traverse`]'s
    /// order exactly.
    pub fn pieces(&self, eye: DVec3, max_faces: u32, mut piece: impl FnMut(Piece)) {
        if self.nodes.is_empty() {
            piece(Piece::Visit(Visit::Guests(NONE, Slot::Straddle)));
            return;
        }
        self.walk(
            0,
            eye,
            true,
            |n| (n != 0 && self.subtree_faces[n as usize] <= max_faces).then_some(Piece::Subtree(n)),
            piece,
        );
    }

    /// The traversal from `root`; a node for which `cut` gives a piece is handed out
    /// whole as that piece ([`Piece::Subtree`] or [`Visit::Culled`]).
    /// Guests' places are visited only with `guests`.
    #[inline(always)]
    fn walk(&self, root: u32, eye: DVec3, guests: bool, cut: impl Fn(u32) -> Option<Piece>, visit: impl FnMut(Piece)) {
        if guests {
            self.walk_with::<true>(root, eye, cut, visit);
        } else {
            self.walk_with::<false>(root, eye, cut, visit);
        }
    }

    /// [`Bsp::walk`] with `guests` a constant: its tests, two or three a node, are
    /// then compiled out (on `many`, a million nodes a frame).
    #[inline(always)]
    fn walk_with<const GUESTS: bool>(
        &self,
        root: u32,
        eye: DVec3,
        cut: impl Fn(u32) -> Option<Piece>,
        mut visit: impl FnMut(Piece),
    ) {
        /// A node whose near side is being walked: what is left of it.
        struct Rest {
            node: u32,
            faces: std::ops::Range<u32>,
            far: u32,
            far_slot: Slot,
            /// The end of the far child's subtree (`far..far_end`).
            far_end: u32,
        }
        // Every node: its near side, its straddling guests and faces, its far side.
        // A node goes on the stack only while its near child's subtree is walked,
        // with what is left of it (so that a large subtree's walk does not have to
        // read the node again from memory); an empty near region is visited at once
        // and the far child entered without a push.
        let mut stack: Vec<Rest> = Vec::new();
        let mut n = root;
        // The end of `n`'s subtree (`n..end`), worked out from the parent's as the
        // walk goes down: the front child's subtree ends where the back child's
        // begins (depth-first numbering, front child first).
        let mut end = root + self.subtree_nodes.get(root as usize).copied().unwrap_or(0);
        if end - root <= SMALL_SUBTREE {
            self.prefetch_nodes(root, end);
        }
        'enter: loop {
            // Enter node `n`.
            let mut rest = if let Some(whole) = cut(n) {
                visit(whole);
                None
            } else {
                let node = &self.nodes[n as usize];
                let eye_front = node.plane.distance(eye) >= 0.0;
                let (near, near_slot, far, far_slot) = if eye_front {
                    (node.front, Slot::Front, node.back, Slot::Back)
                } else {
                    (node.back, Slot::Back, node.front, Slot::Front)
                };
                debug_assert!(node.front == NONE || node.front == n + 1);
                let (near_end, far_end);
                if end - n > SMALL_SUBTREE {
                    let front_end = if node.back != NONE { node.back } else { end };
                    (near_end, far_end) = if eye_front { (front_end, end) } else { (end, front_end) };
                    // A small child's nodes asked for at once on the way in, rather
                    // than one after another as its walk meets them (hints).
                    if near != NONE && near_end - near <= SMALL_SUBTREE {
                        self.prefetch_nodes(near, near_end);
                    }
                    if far != NONE && far_end - far <= SMALL_SUBTREE {
                        self.prefetch_nodes(far, far_end);
                    } else if far != NONE {
                        // Entered after the near side: asked for now, so that a small
                        // near side's walk covers its miss (a hint, no effect on the
                        // order).
                        self.prefetch_node(far);
                    }
                } else {
                    // In a small subtree, whose nodes were asked for on the way in:
                    // the ends matter no more (a child's is taken as itself).
                    (near_end, far_end) = (near, far);
                }
                let rest = Rest { node: n, faces: node.faces.clone(), far, far_slot, far_end };
                if near != NONE {
                    stack.push(rest);
                    n = near;
                    end = near_end;
                    continue 'enter;
                }
                if GUESTS {
                    visit(Piece::Visit(Visit::Guests(n, near_slot)));
                }
                Some(rest)
            };
            // Leave the near side of `rest` (or of the nodes on the stack).
            loop {
                let Some(Rest { node, faces, far, far_slot, far_end }) = rest.take().or_else(|| stack.pop()) else {
                    return;
                };
                if GUESTS {
                    visit(Piece::Visit(Visit::Guests(node, Slot::Straddle)));
                }
                for f in faces {
                    visit(Piece::Visit(Visit::Face(f)));
                }
                if far != NONE {
                    n = far;
                    end = far_end;
                    continue 'enter;
                }
                if GUESTS {
                    visit(Piece::Visit(Visit::Guests(node, far_slot)));
                }
            }
        }
    }

    /// Where a moving model's bounding sphere goes: the deepest node whose plane it
    /// straddles ([`Slot::Straddle`], emitted just before that node's faces), or the
    /// empty region beside a node that it lies in wholly. With no tree at all the
    /// answer is `(NONE, Straddle)`.
    pub fn attach(&self, center: DVec3, radius: f64) -> (u32, Slot) {
        if self.nodes.is_empty() {
            return (NONE, Slot::Straddle);
        }
        let mut n = 0u32;
        loop {
            let node = &self.nodes[n as usize];
            let d = node.plane.distance(center);
            let (next, slot) = if d > radius {
                (node.front, Slot::Front)
            } else if d < -radius {
                (node.back, Slot::Back)
            } else {
                return (n, Slot::Straddle);
            };
            if next == NONE {
                return (n, slot);
            }
            n = next;
        }
    }
}

/// One step of a front-to-back traversal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Visit {
    /// A face of the tree.
    Face(u32),
    /// The place of the guests (moving models, light points) attached at a node.
    Guests(u32, Slot),
    /// The whole subtree of a node, rejected at once ([`Bsp::traverse_subtree_culled`]):
    /// its faces are [`Bsp::subtree_face_range`], and none of its visits is made.
    Culled(u32),
}

/// A piece of a front-to-back traversal cut for several workers ([`Bsp::pieces`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Piece {
    /// One visit.
    Visit(Visit),
    /// The whole subtree of a node, in its own front-to-back order.
    Subtree(u32),
}

/// Where, relative to a node, a moving model is emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Slot {
    /// Its sphere straddles the node's plane: emitted just before the node's faces.
    Straddle,
    /// It lies in the node's empty front region.
    Front,
    /// It lies in the node's empty back region.
    Back,
}

/// Splits a convex polygon by a plane into its front and back parts (vertices within
/// `eps` of the plane go to both).
pub fn split_polygon(vs: &[BspVertex], plane: &Plane, eps: f64) -> (Vec<BspVertex>, Vec<BspVertex>) {
    let mut front = Vec::with_capacity(vs.len() + 1);
    let mut back = Vec::with_capacity(vs.len() + 1);
    let n = vs.len();
    for i in 0..n {
        let a = vs[i];
        let b = vs[(i + 1) % n];
        let da = plane.distance(a.position);
        let db = plane.distance(b.position);
        if da >= -eps {
            front.push(a);
        }
        if da <= eps {
            back.push(a);
        }
        if (da > eps && db < -eps) || (da < -eps && db > eps) {
            let t = da / (da - db);
            let p = BspVertex {
                position: a.position + (b.position - a.position) * t,
                normal: a.normal.lerp(b.normal, t as f32).normalize_or_zero(),
                intensity: a.intensity + (b.intensity - a.intensity) * t as f32,
            };
            front.push(p);
            back.push(p);
        }
    }
    (front, back)
}

/// Area of a planar polygon (for tests and statistics).
pub fn polygon_area(vs: &[BspVertex]) -> f64 {
    if vs.len() < 3 {
        return 0.0;
    }
    let p0 = vs[0].position;
    let mut n = DVec3::ZERO;
    for i in 1..vs.len() - 1 {
        n += (vs[i].position - p0).cross(vs[i + 1].position - p0);
    }
    n.length() * 0.5
}

#[cfg(test)]
mod tests {
    //! The builder against its definition: the straightforward builder it replaced
    //! (each face's vertices read at every test, one list per node), kept here.
    use super::*;
    use proptest::prelude::*;

    impl Bsp {
        fn reference_build(faces: Vec<BspFace>) -> Self {
            let input = faces.len();
            let extent =
                faces.iter().flat_map(|f| f.vertices.iter()).fold(1.0f64, |m, v| m.max(v.position.abs().max_element()));
            let mut bsp = Bsp { eps: extent * PLANE_EPS, faces, ..Bsp::default() };
            bsp.stats.input_faces = input;
            if bsp.faces.is_empty() {
                return bsp;
            }
            // Work stack of nodes to build.
            struct Work {
                /// The parent and whether this is its front child.
                link: Option<(u32, bool)>,
                /// The faces in this node's region.
                list: Vec<u32>,
                depth: usize,
            }
            let all: Vec<u32> = (0..bsp.faces.len() as u32).collect();
            // Each node's faces while building (numbered as built; renumbered at the end).
            let mut node_faces: Vec<Vec<u32>> = Vec::new();
            let mut stack = vec![Work { link: None, list: all, depth: 1 }];
            while let Some(Work { link, list, depth }) = stack.pop() {
                let node = bsp.nodes.len() as u32;
                if let Some((parent, front)) = link {
                    let p = &mut bsp.nodes[parent as usize];
                    if front {
                        p.front = node;
                    } else {
                        p.back = node;
                    }
                }
                bsp.stats.depth = bsp.stats.depth.max(depth);
                let (mut plane, mut owner) = bsp.reference_choose_plane(&list, false);
                if owner.is_none() && !bsp.reference_separates(&list, &plane) {
                    // The sample promised progress the whole list does not give.
                    (plane, owner) = bsp.reference_choose_plane(&list, true);
                }
                let axis = owner.is_none();
                if axis {
                    bsp.stats.axis_nodes += 1;
                }
                let mut on = Vec::new();
                let mut front = Vec::new();
                let mut back = Vec::new();
                for &fi in &list {
                    // The face whose plane this is lies in it, whatever rounding says.
                    let side = if Some(fi) == owner { Side::On } else { bsp.reference_side(fi, &plane) };
                    match side {
                        Side::Front => front.push(fi),
                        Side::Back => back.push(fi),
                        Side::On => {
                            if axis {
                                // A free plane: the face goes where its normal points.
                                if bsp.faces[fi as usize].plane.normal.dot(plane.normal) >= 0.0 {
                                    front.push(fi)
                                } else {
                                    back.push(fi)
                                }
                            } else {
                                on.push(fi)
                            }
                        }
                        Side::Straddle => {
                            let (f, b) = bsp.reference_split(fi, &plane);
                            bsp.stats.splits += 1;
                            front.extend(f);
                            back.extend(b);
                        }
                    }
                }
                bsp.nodes.push(BspNode { plane, front: NONE, back: NONE, faces: 0..0 });
                node_faces.push(on);
                if !back.is_empty() {
                    stack.push(Work { link: Some((node, false)), list: back, depth: depth + 1 });
                }
                if !front.is_empty() {
                    stack.push(Work { link: Some((node, true)), list: front, depth: depth + 1 });
                }
            }
            bsp.reference_renumber_faces(node_faces);
            bsp.stats.nodes = bsp.nodes.len();
            bsp.stats.faces = bsp.faces.len();
            bsp.make_records();
            bsp
        }

        /// Numbers the faces in node order, so that each node's faces are a range and the
        /// faces of nearby nodes lie together in memory for the traversal and the GP (a
        /// pure renumbering: the tree and its order are unchanged). A face that no node
        /// holds (none is expected) keeps a place after the others.
        fn reference_renumber_faces(&mut self, node_faces: Vec<Vec<u32>>) {
            let mut old: Vec<Option<BspFace>> = std::mem::take(&mut self.faces).into_iter().map(Some).collect();
            let mut faces = Vec::with_capacity(old.len());
            for (node, list) in self.nodes.iter_mut().zip(node_faces) {
                let start = faces.len() as u32;
                faces.extend(list.into_iter().filter_map(|f| old[f as usize].take()));
                node.faces = start..faces.len() as u32;
            }
            faces.extend(old.into_iter().flatten());
            self.faces = faces;
        }

        fn reference_side(&self, fi: u32, plane: &Plane) -> Side {
            let (mut f, mut b) = (false, false);
            for v in &self.faces[fi as usize].vertices {
                let d = plane.distance(v.position);
                if d > self.eps {
                    f = true;
                } else if d < -self.eps {
                    b = true;
                }
            }
            match (f, b) {
                (true, true) => Side::Straddle,
                (true, false) => Side::Front,
                (false, true) => Side::Back,
                (false, false) => Side::On,
            }
        }

        /// Whether a free plane leaves faces on both sides (or cuts one), so that the
        /// recursion makes progress.
        fn reference_separates(&self, list: &[u32], plane: &Plane) -> bool {
            let (mut f, mut b) = (false, false);
            for &fi in list {
                match self.reference_side(fi, plane) {
                    Side::Straddle => return true,
                    Side::Front => f = true,
                    Side::Back => b = true,
                    Side::On => {
                        if self.faces[fi as usize].plane.normal.dot(plane.normal) >= 0.0 {
                            f = true
                        } else {
                            b = true
                        }
                    }
                }
                if f && b {
                    return true;
                }
            }
            false
        }

        /// Picks the plane for a node: `(plane, the face whose plane it is)`, `None` for a
        /// free axis-aligned plane; only face planes when `faces_only`.
        fn reference_choose_plane(&self, list: &[u32], faces_only: bool) -> (Plane, Option<u32>) {
            let step = (list.len() / COST_SAMPLE).max(1);
            let sample: Vec<u32> = list.iter().step_by(step).copied().collect();
            let mut best: Option<(i64, Plane, Option<u32>)> = None;
            let consider =
                |cost: i64, plane: Plane, owner: Option<u32>, best: &mut Option<(i64, Plane, Option<u32>)>| {
                    if best.as_ref().is_none_or(|b| cost < b.0) {
                        *best = Some((cost, plane, owner));
                    }
                };
            if list.len() > AUTO_PARTITION_AT && !faces_only {
                for axis in 0..3 {
                    let mut cents: Vec<f64> = sample.iter().map(|&fi| self.reference_centroid(fi)[axis]).collect();
                    let mid = cents.len() / 2;
                    let (_, &mut median, _) = cents.select_nth_unstable_by(mid, f64::total_cmp);
                    // Vertex coordinates nearest the median on either side.
                    let (mut below, mut above) = (f64::MIN, f64::MAX);
                    for &fi in &sample {
                        for v in &self.faces[fi as usize].vertices {
                            let c = v.position[axis];
                            if c <= median && c > below {
                                below = c;
                            }
                            if c >= median && c < above {
                                above = c;
                            }
                        }
                    }
                    for pos in [median, below, above] {
                        if !pos.is_finite() || pos == f64::MIN || pos == f64::MAX {
                            continue;
                        }
                        let mut normal = DVec3::ZERO;
                        normal[axis] = 1.0;
                        let plane = Plane { normal, d: pos };
                        if let Some(cost) = self.reference_cost(&sample, &plane, true) {
                            consider(cost, plane, None, &mut best);
                        }
                    }
                }
            }
            // On a large node a free plane is taken when there is one: face planes are
            // for the small nodes (and for when no free plane makes progress).
            if let Some((_, plane, None)) = best {
                if list.len() > FACE_PLANES_BELOW {
                    return (plane, None);
                }
            }
            // Face planes of a few spread-out faces.
            let candidates = 8.min(list.len());
            for k in 0..candidates {
                let fi = list[k * list.len() / candidates];
                let plane = self.faces[fi as usize].plane;
                let cost = self.reference_cost(&sample, &plane, false).unwrap_or(i64::MAX / 2);
                consider(cost, plane, Some(fi), &mut best);
            }
            let (_, plane, owner) = best.expect("a node has at least one face");
            (plane, owner)
        }

        /// Cost of a plane over a sample of faces; `None` if a free plane leaves one side
        /// empty (it would not make progress).
        fn reference_cost(&self, sample: &[u32], plane: &Plane, free: bool) -> Option<i64> {
            let (mut f, mut b, mut s) = (0i64, 0i64, 0i64);
            for &fi in sample {
                match self.reference_side(fi, plane) {
                    Side::Front => f += 1,
                    Side::Back => b += 1,
                    Side::Straddle => s += 1,
                    Side::On => {
                        if free {
                            if self.faces[fi as usize].plane.normal.dot(plane.normal) >= 0.0 {
                                f += 1
                            } else {
                                b += 1
                            }
                        }
                    }
                }
            }
            if free && (f + s == 0 || b + s == 0) {
                return None;
            }
            Some(s * SPLIT_COST + (f - b).abs())
        }

        fn reference_centroid(&self, fi: u32) -> DVec3 {
            let vs = &self.faces[fi as usize].vertices;
            vs.iter().map(|v| v.position).sum::<DVec3>() / vs.len() as f64
        }

        /// Splits face `fi` by `plane`: the front piece replaces it, the back piece is
        /// appended. Returns the (front, back) face indices (a sliver below rounding may
        /// vanish).
        fn reference_split(&mut self, fi: u32, plane: &Plane) -> (Option<u32>, Option<u32>) {
            let face = self.faces[fi as usize].clone();
            let (fv, bv) = split_polygon(&face.vertices, plane, self.eps);
            let mut out = (None, None);
            let mut front_used = false;
            for (verts, is_front) in [(fv, true), (bv, false)] {
                if verts.len() < 3 {
                    continue;
                }
                let piece = BspFace { vertices: verts, ..face.clone() };
                let idx = if !front_used {
                    front_used = true;
                    self.faces[fi as usize] = piece;
                    fi
                } else {
                    self.faces.push(piece);
                    (self.faces.len() - 1) as u32
                };
                if is_front {
                    out.0 = Some(idx);
                } else {
                    out.1 = Some(idx);
                }
            }
            out
        }
    }

    /// A small random number generator for the faces (xorshift64*).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    /// A face over `points` (convex, in order) with its plane as the GP makes it
    /// (Newell's normal, `d` at the first vertex).
    fn face_of(points: &[DVec3], k: usize) -> Option<BspFace> {
        let vertices: Vec<BspVertex> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| BspVertex {
                position: p,
                normal: Vec3::new(i as f32, 1.0, 0.5).normalize(),
                intensity: 0.25 * i as f32,
            })
            .collect();
        let p0 = points[0];
        let mut n = DVec3::ZERO;
        for i in 1..points.len() - 1 {
            n += (points[i] - p0).cross(points[i + 1] - p0);
        }
        let len = n.length();
        (len > 1e-9).then(|| {
            let normal = n / len;
            BspFace {
                plane: Plane { normal, d: normal.dot(p0) },
                vertices,
                material: (k % 5) as u32,
                instance: (k % 3) as u32,
                face: k as u32,
            }
        })
    }

    /// `n` random convex faces (3 to 6 vertices) in a box of side 20: on planes of
    /// random orientation, or on axis planes (some shared, so coplanar) with
    /// coordinates on a grid of `grid` (0: none) and zeros of either sign, many of
    /// them crossing one another (so split).
    fn random_faces(seed: u64, n: usize, grid: f64) -> Vec<BspFace> {
        let mut rng = Rng(seed | 1);
        let snap = |x: f64, rng: &mut Rng| {
            let x = if grid > 0.0 { (x / grid).round() * grid } else { x };
            if x == 0.0 && rng.next() & 1 == 1 {
                -0.0
            } else {
                x
            }
        };
        let mut planes: Vec<(usize, f64)> = Vec::new();
        let mut faces = Vec::with_capacity(n);
        let mut k = 0;
        while faces.len() < n {
            k += 1;
            let sides = 3 + rng.below(4);
            // Smaller faces in larger sets, which split less.
            let r = rng.range(0.3, if n > 500 { 1.5 } else { 4.0 });
            let c = DVec3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), rng.range(-10.0, 10.0));
            let turn = rng.range(0.0, std::f64::consts::TAU);
            let angles: Vec<f64> = (0..sides).map(|i| turn + std::f64::consts::TAU * i as f64 / sides as f64).collect();
            let points: Vec<DVec3> = if rng.below(3) == 0 {
                // A plane of random orientation.
                let normal =
                    DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or_zero();
                if normal == DVec3::ZERO {
                    continue;
                }
                let u = normal.any_orthonormal_vector();
                let v = normal.cross(u);
                angles.iter().map(|a| c + (u * a.cos() + v * a.sin()) * r).collect()
            } else {
                // An axis plane, often one met before.
                let (axis, at) = if !planes.is_empty() && rng.below(2) == 0 {
                    planes[rng.below(planes.len())]
                } else {
                    let p = (rng.below(3), snap(c[rng.below(3)], &mut rng));
                    planes.push(p);
                    p
                };
                let flip = rng.below(2) == 0;
                angles
                    .iter()
                    .map(|a| {
                        let (s, t) = (a.cos() * r, if flip { -a.sin() * r } else { a.sin() * r });
                        let mut p = DVec3::ZERO;
                        p[axis] = at;
                        p[(axis + 1) % 3] = snap(c[(axis + 1) % 3] + s, &mut rng);
                        p[(axis + 2) % 3] = snap(c[(axis + 2) % 3] + t, &mut rng);
                        p
                    })
                    .collect()
            };
            if let Some(f) = face_of(&points, k) {
                faces.push(f);
            }
        }
        faces
    }

    /// Where two trees' Debug prints (every number exactly, zeros with their signs)
    /// first differ, with what is around it; `None` if they are the same to the bit.
    fn difference(built: &Bsp, reference: &Bsp) -> Option<String> {
        let (a, b) = (format!("{built:?}"), format!("{reference:?}"));
        let at = a
            .bytes()
            .zip(b.bytes())
            .position(|(x, y)| x != y)
            .or((a.len() != b.len()).then_some(a.len().min(b.len())))?;
        let around = |s: &str| s[at.saturating_sub(300)..(at + 100).min(s.len())].to_string();
        Some(format!("at byte {at}:\n built     ...{}\n reference ...{}", around(&a), around(&b)))
    }

    /// Runs `f` on a rayon pool of `threads` threads (1 to 3; made once).
    fn on_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        static POOLS: std::sync::OnceLock<Vec<rayon::ThreadPool>> = std::sync::OnceLock::new();
        let pools = POOLS
            .get_or_init(|| (1..=3).map(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()).collect());
        pools[threads - 1].install(f)
    }

    /// The subtrees' sizes below which the tests build them apart ([`Bsp::build_apart`]):
    /// none, large ones, small ones, single faces.
    fn apart_sizes(n: usize) -> [usize; 4] {
        [0, n / 3 + 1, n / 16 + 2, 2]
    }

    /// The built trees are the same (`==`, and to the bit): [`Bsp::build`] and
    /// [`Bsp::build_apart`] at several sizes, on pools of 1, 2 and 3 threads.
    fn assert_same(faces: Vec<BspFace>) -> Result<(), TestCaseError> {
        let reference = Bsp::reference_build(faces.clone());
        let built = Bsp::build(faces.clone());
        prop_assert!(built == reference, "trees differ: {:?}", difference(&built, &reference));
        prop_assert_eq!(difference(&built, &reference), None);
        for apart_below in apart_sizes(faces.len()) {
            for threads in 1..=3 {
                let built = on_pool(threads, || Bsp::build_apart(faces.clone(), apart_below));
                prop_assert!(
                    built == reference,
                    "apart below {apart_below}, {threads} threads: trees differ: {:?}",
                    difference(&built, &reference)
                );
                prop_assert_eq!(difference(&built, &reference), None);
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(40))]

        /// The builder builds the tree its definition does, whatever the faces:
        /// every size class ([`AUTO_PARTITION_AT`], [`FACE_PLANES_BELOW`],
        /// [`COST_SAMPLE`] sampling), coplanar faces, faces on axis planes, faces
        /// split.
        #[test]
        fn the_builder_builds_the_reference_tree(
            seed in any::<u64>(),
            n in prop_oneof![1usize..=AUTO_PARTITION_AT + 2, 10usize..=3 * FACE_PLANES_BELOW, 900usize..2600],
            grid in prop_oneof![Just(0.0), Just(0.5), Just(2.0)],
        ) {
            assert_same(random_faces(seed, n, grid))?;
        }
    }

    /// The cases the proptest may miss: no face, one face, and large sets.
    #[test]
    fn the_builder_builds_the_reference_tree_on_large_sets() {
        assert_eq!(Bsp::build(Vec::new()), Bsp::reference_build(Vec::new()));
        for (seed, n, grid) in [(1, 1, 0.0), (2, 4000, 0.5), (3, 4000, 0.0), (4, 3000, 2.0)] {
            let faces = random_faces(seed, n, grid);
            assert!(Bsp::build(faces.clone()).stats.splits > 0 || n < 2, "no split in case {seed}");
            assert_same(faces).unwrap_or_else(|e| panic!("case {seed}: {e}"));
        }
    }

    /// A face plane's box pre-test ([`Builder::box_side`]) answers, when it
    /// answers, what every vertex's distance does ([`Builder::side`]): random faces
    /// against every face's plane, and against planes through their vertices (the
    /// face's own, tilted a little, random, axes) moved by up to 2 `eps` either way
    /// in halves (so vertices lie at and about the borders of `eps`). Each of its
    /// three answers is given; widening a border by an `eps` fails it.
    #[test]
    fn the_box_side_is_every_vertex_side() {
        let mut given = [0usize; 3];
        for (seed, grid) in [(11, 0.0), (12, 0.5), (13, 2.0)] {
            let faces = random_faces(seed, 200, grid);
            let items: Vec<Item> = faces.iter().enumerate().map(|(i, f)| Item::of(i as u32, f)).collect();
            let builder = Builder::new(faces);
            let mut rng = Rng(seed);
            let mut planes: Vec<Plane> = builder.faces.iter().map(|f| f.plane).collect();
            for f in builder.faces.iter().take(40) {
                for v in &f.vertices {
                    let random = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))
                        .normalize_or_zero();
                    // The face's own plane tilted so that its vertices spread over
                    // about an `eps`.
                    let wobble = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                    let tilted = (f.plane.normal + wobble * builder.eps).normalize();
                    for normal in [f.plane.normal, tilted, random, DVec3::X, -DVec3::Z] {
                        for k in [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0] {
                            planes.push(Plane { normal, d: normal.dot(v.position) + k * builder.eps });
                        }
                    }
                }
            }
            for plane in &planes {
                for item in &items {
                    if let Some(side) = builder.box_side(item, plane) {
                        assert_eq!(side, builder.side(item.face, plane), "face {} against {plane:?}", item.face);
                        given[match side {
                            Side::Front => 0,
                            Side::Back => 1,
                            _ => 2,
                        }] += 1;
                    }
                }
            }
        }
        assert!(given.iter().all(|&g| g > 0), "answers given (front, back, on): {given:?}");
    }

    /// [`Bsp::build`] itself builds apart from [`APART_FROM`] faces: the tree is
    /// the reference's, on pools of 1, 2 and 3 threads.
    #[test]
    fn the_parallel_build_builds_the_reference_tree() {
        let faces = random_faces(5, APART_FROM + 500, 0.5);
        let reference = Bsp::reference_build(faces.clone());
        assert!(reference.stats.splits > 0);
        for threads in 1..=3 {
            let built = on_pool(threads, || Bsp::build(faces.clone()));
            assert!(built == reference, "{threads} threads: {:?}", difference(&built, &reference));
            assert_eq!(difference(&built, &reference), None, "{threads} threads");
        }
    }
}

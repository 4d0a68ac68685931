//! The hierarchy of hierarchical radiosity: input polygons are the leaves of a binary tree
//! of clusters (a bounding volume hierarchy built over them), and every polygon refines on
//! demand into sub-elements (four for triangles and quads, two for larger convex polygons).
//!
//! Nodes live in one arena; children are contiguous. A node's geometry summary — area,
//! vector area Σ A·n, centroid, bounding sphere, box, normal cone — serves the link oracle.

use crate::geometry::{newell, Polygon};
use glam::DVec3;

/// No node.
pub const NONE: u32 = u32::MAX;

/// One input polygon (a scene surface) with the data the solver needs.
#[derive(Debug, Clone)]
pub struct InputPolygon {
    /// The scene surface it is.
    pub surface: u32,
    /// Object index (into the scene's object names).
    pub object: u32,
    /// Reflectance ρ per channel.
    pub reflectance: [f64; 3],
    /// Emitted exitance E = π·L_e per channel, W·m⁻².
    pub exitance: [f64; 3],
    /// Its node.
    pub node: u32,
    /// Whether it sees nothing but the backs of other surfaces (floor under a box standing
    /// on it): it can neither receive nor give light, and the tree keeps it apart from the
    /// rest so that no cluster link spreads light onto it ([`Tree::build`]).
    pub buried: bool,
    /// Whether another surface passes through it (a leg through a seat, a table leg through
    /// the top it holds): some of its leaves lie partly inside that object and see only the
    /// backs of its faces there, so they gather less than their whole hemisphere
    /// ([`super::Hierarchical::seen_fraction`]).
    pub pierced: bool,
}

/// What a node is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A group of input polygons (a node of the cluster tree).
    Cluster,
    /// An input polygon or a piece of one; `input` indexes [`Tree::inputs`].
    Polygon {
        /// The input polygon it is (part of).
        input: u32,
    },
}

/// A node of the hierarchy.
#[derive(Debug, Clone)]
pub struct Node {
    /// Parent node, or [`NONE`] for the root.
    pub parent: u32,
    /// First child; children are `first_child..first_child + child_count`.
    pub first_child: u32,
    /// Number of children (0 for a leaf).
    pub child_count: u32,
    /// Cluster or polygon.
    pub kind: Kind,
    /// Polygon nodes: range of their vertices in [`Tree::vertices`].
    pub vertex_start: u32,
    /// Number of vertices (0 for clusters).
    pub vertex_count: u32,
    /// Range of input polygons under the node, in [`Tree::leaf_order`] positions.
    pub leaves: (u32, u32),
    /// Area, m².
    pub area: f64,
    /// Σ A_i n_i over the node's polygons, m².
    pub vector_area: DVec3,
    /// Σ A_i max(0, ±n_i · e_k) over the node's polygons for the axes e_k (x, y, z), m²:
    /// `[+x, −x, +y, −y, +z, −z]`, the areas facing each way, for bounds of the projected
    /// area (see [`Node::projected_bound`]).
    pub facing: [f64; 6],
    /// Area centroid, m.
    pub centre: DVec3,
    /// Radius of a sphere about `centre` holding the node, m.
    pub radius: f64,
    /// Corners of the node's axis-aligned bounding box, m.
    pub bounds: [DVec3; 2],
    /// Unit axis of the normal cone (the polygon's normal for polygon nodes).
    pub axis: DVec3,
    /// Cosine of the normal cone's half-angle: 1 for a polygon, −1 when the normals span
    /// more than a hemisphere.
    pub cone_cos: f64,
    /// Subdivision depth below the input polygon (0 for clusters and input polygons).
    pub depth: u16,
    /// Polygon nodes: how many pieces [`split_polygon`] makes of it (0 for clusters; kept,
    /// not worked out from the vertices at every oracle call: 1.4 % of the Cornell box's
    /// CPU was that).
    pub parts: u8,
    /// Polygon nodes: the second moment of area about the centroid in the plane,
    /// ∫ (u², uv, v²) dA over the polygon, m⁴, with (u, v) the coordinates along
    /// `axis.any_orthonormal_pair()` (for least-squares radiosity gradients).
    pub plane_moment: [f64; 3],
}

impl Node {
    /// Whether this is a polygon (or piece of one).
    pub fn is_polygon(&self) -> bool {
        matches!(self.kind, Kind::Polygon { .. })
    }

    /// Children, as a range of node indices.
    pub fn children(&self) -> std::ops::Range<u32> {
        self.first_child..self.first_child + self.child_count
    }

    /// An upper bound of the node's projected area Σ A_i max(0, n_i · w) (one-sided
    /// polygons, m²) over all unit directions w within `spread` radians of the unit vector
    /// `toward`: max(0, n · w) ≤ Σ_k |w_k| max(0, sign(w_k) n_k) over the axes k, where each
    /// |w_k| is at most |toward_k| + 2 sin(spread/2) (the chord) and both signs count where
    /// the chord reaches across zero; never more than the area.
    pub fn projected_bound(&self, toward: DVec3, spread: f64) -> f64 {
        let chord = 2.0 * (0.5 * spread.clamp(0.0, std::f64::consts::PI)).sin();
        let mut sum = 0.0;
        for k in 0..3 {
            let (plus, minus) = (self.facing[2 * k], self.facing[2 * k + 1]);
            let w = toward[k];
            let facing = if w.abs() <= chord {
                plus.max(minus)
            } else if w > 0.0 {
                plus
            } else {
                minus
            };
            sum += (w.abs() + chord) * facing;
        }
        sum.min(self.area)
    }
}

/// The facing areas `[+x, −x, +y, −y, +z, −z]` of a polygon (see [`Node::facing`]).
fn facing(normal: DVec3, area: f64) -> [f64; 6] {
    let mut f = [0.0; 6];
    for k in 0..3 {
        f[2 * k] = area * normal[k].max(0.0);
        f[2 * k + 1] = area * (-normal[k]).max(0.0);
    }
    f
}

/// The hierarchy: input polygons, the cluster tree over them, and their sub-elements.
#[derive(Debug, Clone, Default)]
pub struct Tree {
    /// Input polygons, in scene order.
    pub inputs: Vec<InputPolygon>,
    /// Every node; node 0 is the root.
    pub nodes: Vec<Node>,
    /// Vertices of polygon nodes, m.
    pub vertices: Vec<DVec3>,
    /// Input polygon indices in the order of the cluster tree's leaves.
    pub leaf_order: Vec<u32>,
    /// Prefix sums of input polygon areas in leaf order (m²), length `inputs + 1`.
    pub area_prefix: Vec<f64>,
    /// Position of each input polygon in `leaf_order`.
    pub leaf_position: Vec<u32>,
    /// Position in `leaf_order` from which the input polygons are buried (their subtree's
    /// leaves; `inputs.len()` when none is).
    pub buried_from: u32,
}

/// Leaves per cluster-tree leaf: one input polygon each, so links can stop at any polygon.
const BINS: usize = 16;
/// Weight of the orientation term in the split cost: a child whose normals disagree
/// (|Σ A n| / Σ A small) costs up to 1 + λ times as much as a flat one.
const ORIENTATION_WEIGHT: f64 = 2.0;

impl Tree {
    /// Whether node `node` holds only buried input polygons (or pieces of one).
    pub fn is_buried(&self, node: u32) -> bool {
        self.nodes[node as usize].leaves.0 >= self.buried_from
    }

    /// The vertices of a polygon node (none once the hierarchy's refinement is finished:
    /// [`super::Hierarchical::finish_refining`]).
    pub fn polygon(&self, node: u32) -> &[DVec3] {
        let n = &self.nodes[node as usize];
        self.vertices
            .get(n.vertex_start as usize..(n.vertex_start + n.vertex_count) as usize)
            .unwrap_or(&[])
    }

    /// Builds the cluster tree over `polygons` (scene surfaces with their data): a binary
    /// tree, top down, each split the cheapest of binned surface-area splits along the three
    /// axes and one split by orientation, with cost Σ_c SA(c)/SA · n_c · (1 + λ(1 − |N_c|/A_c))
    /// (N the vector area, λ = [`ORIENTATION_WEIGHT`]), so that opposite walls and the faces of
    /// a box end up in different subtrees and most clusters have narrow normal cones.
    /// Buried polygons ([`InputPolygon::buried`]) form a subtree of their own under the root:
    /// a cluster's links give every member the same light, and a floor piece under a box in
    /// a cluster with the floor around it would get the light of the floor around it (in the
    /// furnished rooms of the scale benchmark, light that went nowhere after).
    pub fn build(polygons: Vec<(Polygon, InputPolygon)>) -> Tree {
        let mut tree = Tree::default();
        let count = polygons.len();
        #[derive(Clone, Copy)]
        struct Item {
            input: u32,
            centroid: DVec3,
            lo: DVec3,
            hi: DVec3,
            area: f64,
            normal: DVec3,
        }
        let mut items: Vec<Item> = Vec::with_capacity(count);
        let mut outlines: Vec<Polygon> = Vec::with_capacity(count);
        for (i, (poly, input)) in polygons.into_iter().enumerate() {
            let (lo, hi) = poly.bounds();
            items.push(Item {
                input: i as u32,
                centroid: poly.centroid(),
                lo,
                hi,
                area: poly.area(),
                normal: poly.normal(),
            });
            tree.inputs.push(input);
            outlines.push(poly);
        }
        if count == 0 {
            return tree;
        }
        // The buried last; the root's split is between them and the rest.
        let open = partition(&mut items, |it| !tree.inputs[it.input as usize].buried);
        // Build top-down with an explicit stack: (items range, parent, slot for this node).
        tree.nodes.push(placeholder());
        let mut stack: Vec<(usize, usize, u32)> = vec![(0, count, 0)];
        while let Some((start, end, index)) = stack.pop() {
            let slice = &mut items[start..end];
            if slice.len() == 1 {
                let item = &slice[0];
                let poly = &outlines[item.input as usize];
                let parent = tree.nodes[index as usize].parent;
                let node = tree.polygon_node(poly.vertices(), item.input, 0, parent);
                tree.nodes[index as usize] = Node {
                    leaves: (start as u32, end as u32),
                    ..node
                };
                tree.inputs[item.input as usize].node = index;
                continue;
            }
            let mid = if index == 0 && open > 0 && open < count {
                open
            } else {
                start + best_split(slice, |it| (it.centroid, it.lo, it.hi, it.area, it.normal))
            };
            let first = tree.nodes.len() as u32;
            tree.nodes.push(placeholder());
            tree.nodes.push(placeholder());
            tree.nodes[index as usize] = Node {
                parent: tree.nodes[index as usize].parent,
                first_child: first,
                child_count: 2,
                leaves: (start as u32, end as u32),
                ..placeholder()
            };
            tree.nodes[first as usize].parent = index;
            tree.nodes[first as usize + 1].parent = index;
            stack.push((mid, end, first + 1));
            stack.push((start, mid, first));
        }
        tree.buried_from = open as u32;
        tree.leaf_order = items.iter().map(|it| it.input).collect();
        tree.leaf_position = vec![0; count];
        for (pos, &input) in tree.leaf_order.iter().enumerate() {
            tree.leaf_position[input as usize] = pos as u32;
        }
        tree.area_prefix = Vec::with_capacity(count + 1);
        let mut sum = 0.0;
        tree.area_prefix.push(0.0);
        for it in &items {
            sum += it.area;
            tree.area_prefix.push(sum);
        }
        // Parents' summaries, bottom up (children always have larger indices).
        for i in (0..tree.nodes.len()).rev() {
            if tree.nodes[i].kind == Kind::Cluster {
                let parent = tree.nodes[i].parent;
                tree.summarise_cluster(i);
                tree.nodes[i].parent = parent;
            }
        }
        tree
    }

    /// A polygon node for `vertices` (not yet in the arena).
    fn polygon_node(&mut self, vertices: &[DVec3], input: u32, depth: u16, parent: u32) -> Node {
        let start = self.vertices.len() as u32;
        self.vertices.extend_from_slice(vertices);
        polygon_node_at(vertices, start, input, depth, parent)
    }

    /// Sets a cluster's summary from its two children.
    fn summarise_cluster(&mut self, i: usize) {
        let children: Vec<Node> = self.nodes[i]
            .children()
            .map(|c| self.nodes[c as usize].clone())
            .collect();
        let area: f64 = children.iter().map(|c| c.area).sum();
        let vector_area: DVec3 = children.iter().map(|c| c.vector_area).sum();
        let mut facing = [0.0; 6];
        for c in &children {
            for (f, g) in facing.iter_mut().zip(c.facing) {
                *f += g;
            }
        }
        let centre = if area > 0.0 {
            children.iter().map(|c| c.centre * c.area).sum::<DVec3>() / area
        } else {
            children.iter().map(|c| c.centre).sum::<DVec3>() / children.len() as f64
        };
        let radius = children
            .iter()
            .map(|c| c.centre.distance(centre) + c.radius)
            .fold(0.0, f64::max);
        // Normal cone: about the mean normal, wide enough to hold every child's cone.
        let axis = vector_area.try_normalize().unwrap_or(DVec3::Z);
        let mut half: f64 = 0.0;
        for c in &children {
            let child_half = c.cone_cos.clamp(-1.0, 1.0).acos();
            let between = axis.dot(c.axis).clamp(-1.0, 1.0).acos();
            half = half.max(between + child_half);
        }
        let bounds = children
            .iter()
            .fold([DVec3::INFINITY, DVec3::NEG_INFINITY], |[lo, hi], c| {
                [lo.min(c.bounds[0]), hi.max(c.bounds[1])]
            });
        let node = &mut self.nodes[i];
        node.kind = Kind::Cluster;
        node.bounds = bounds;
        node.area = area;
        node.vector_area = vector_area;
        node.facing = facing;
        node.centre = centre;
        node.radius = radius;
        node.axis = axis;
        node.cone_cos = if half >= std::f64::consts::PI {
            -1.0
        } else {
            half.cos()
        };
    }

    /// The children of polygon node `node` ([`split_polygon`]), not yet in the arena (their
    /// vertices numbered from 0 in the pieces' own list; [`Tree::attach`] puts them there):
    /// none for a node that has children or is a cluster. It only reads the tree, so that
    /// many nodes' pieces can be made at once.
    pub fn pieces(&self, node: u32) -> Option<Pieces> {
        let n = &self.nodes[node as usize];
        let Kind::Polygon { input } = n.kind else {
            return None;
        };
        if n.child_count > 0 {
            return None;
        }
        let mut pieces = Pieces::default();
        for piece in split_polygon(self.polygon(node)) {
            let start = pieces.vertices.len() as u32;
            pieces.vertices.extend_from_slice(&piece);
            pieces.nodes.push(Node {
                leaves: n.leaves,
                ..polygon_node_at(&piece, start, input, n.depth + 1, node)
            });
        }
        Some(pieces)
    }

    /// Puts the children `pieces` of `node` (from [`Tree::pieces`]) in the arena.
    pub fn attach(&mut self, node: u32, pieces: Pieces) {
        let first = self.nodes.len() as u32;
        let offset = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&pieces.vertices);
        let count = pieces.nodes.len() as u32;
        self.nodes.extend(pieces.nodes.into_iter().map(|mut child| {
            child.vertex_start += offset;
            child
        }));
        let parent = &mut self.nodes[node as usize];
        parent.first_child = first;
        parent.child_count = count;
    }

    /// `count` points on the node's surfaces, spread by area, each with its surface's
    /// normal: for a polygon its Gauss points of order ⌈√count⌉; for a cluster, point k lies
    /// in the member polygon at cumulative-area fraction (k + ½)/count along the leaf order, at
    /// the k-th point of a Halton sequence mapped uniformly onto that polygon — so the points
    /// cover every member in proportion to its area, not only the members' centroids.
    pub fn sample_points(&self, node: u32, count: usize) -> Vec<(DVec3, DVec3)> {
        let n = &self.nodes[node as usize];
        if n.is_polygon() {
            let order = (count as f64).sqrt().ceil().max(1.0) as usize;
            let mut pts = Vec::new();
            crate::formfactor::quadrature::element_points(
                self.polygon(node),
                n.centre,
                order,
                &mut pts,
            );
            return pts.into_iter().map(|(p, _)| (p, n.axis)).collect();
        }
        let (lo, hi) = (n.leaves.0 as usize, n.leaves.1 as usize);
        let (a0, a1) = (self.area_prefix[lo], self.area_prefix[hi]);
        let mut out = Vec::with_capacity(count);
        for k in 0..count {
            let target = a0 + (a1 - a0) * (k as f64 + 0.5) / count as f64;
            let pos = (self.area_prefix[lo..=hi].partition_point(|&s| s <= target) + lo)
                .saturating_sub(1)
                .clamp(lo, hi - 1);
            let input = self.leaf_order[pos] as usize;
            let leaf = self.inputs[input].node;
            let point = point_in_polygon(
                self.polygon(leaf),
                halton(k as u32 + 1, 2),
                halton(k as u32 + 1, 3),
            );
            out.push((point, self.nodes[leaf as usize].axis));
        }
        out
    }
}

/// The radical inverse of `i` in base `b` (Halton's low-discrepancy sequence), in [0, 1).
fn halton(mut i: u32, b: u32) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r
}

/// The point of a convex polygon at (u, v) ∈ [0, 1)² under an area-preserving map: `u`
/// chooses a fan triangle by area and, rescaled, with `v` a uniform point in it.
fn point_in_polygon(vertices: &[DVec3], u: f64, v: f64) -> DVec3 {
    let v0 = vertices[0];
    let areas: Vec<f64> = vertices[1..]
        .windows(2)
        .map(|w| (w[0] - v0).cross(w[1] - v0).length())
        .collect();
    let total: f64 = areas.iter().sum();
    if total <= 0.0 {
        return v0;
    }
    let mut acc = 0.0;
    let mut pick = areas.len() - 1;
    let mut local = u;
    for (i, a) in areas.iter().enumerate() {
        if u * total < acc + a || i + 1 == areas.len() {
            pick = i;
            local = ((u * total - acc) / a.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
            break;
        }
        acc += a;
    }
    let (a, b) = (vertices[pick + 1], vertices[pick + 2]);
    let s = local.sqrt();
    v0 * (1.0 - s) + a * (s * (1.0 - v)) + b * (s * v)
}

fn placeholder() -> Node {
    Node {
        parent: NONE,
        first_child: NONE,
        child_count: 0,
        kind: Kind::Cluster,
        vertex_start: 0,
        vertex_count: 0,
        leaves: (0, 0),
        area: 0.0,
        vector_area: DVec3::ZERO,
        facing: [0.0; 6],
        centre: DVec3::ZERO,
        radius: 0.0,
        bounds: [DVec3::ZERO; 2],
        axis: DVec3::Z,
        cone_cos: 1.0,
        depth: 0,
        parts: 0,
        plane_moment: [0.0; 3],
    }
}

/// ∫ (u², uv, v²) dA about `centre` over a convex polygon, in the basis
/// `normal.any_orthonormal_pair()`: per fan triangle (centre, b, d) with b, d relative to
/// the centre, ∫ y yᵀ dA = A/12 (b bᵀ + d dᵀ + (b + d)(b + d)ᵀ).
fn plane_moment(vertices: &[DVec3], centre: DVec3, normal: DVec3) -> [f64; 3] {
    let (t, s) = normal.any_orthonormal_pair();
    let mut m = [0.0; 3];
    let count = vertices.len();
    for i in 0..count {
        let (b, d) = (vertices[i] - centre, vertices[(i + 1) % count] - centre);
        let area = 0.5 * b.cross(d).dot(normal);
        let (bu, bv, du, dv) = (b.dot(t), b.dot(s), d.dot(t), d.dot(s));
        let (su, sv) = (bu + du, bv + dv);
        m[0] += area / 12.0 * (bu * bu + du * du + su * su);
        m[1] += area / 12.0 * (bu * bv + du * dv + su * sv);
        m[2] += area / 12.0 * (bv * bv + dv * dv + sv * sv);
    }
    m
}

/// Longer over shorter side beyond which a quad splits in two across its length rather than
/// in four: a 2 : 1 quad gives two squares.
const LONG_QUAD: f64 = 2.0;
/// Longest edge over the height on it beyond which a triangle is bisected on that edge
/// rather than split in four (a right isosceles triangle has 2, an equilateral 1.15). At 4
/// the halves have 2.5, a clear gain; at 2.5 they would have 2.05, hardly one, and the
/// Cornell box's contact-split floor pieces then split differently for no better result
/// (worst polygon 9.1 % instead of 7.7 % at ε = 0.02).
const LONG_TRIANGLE: f64 = 4.0;

/// The polygon node for `vertices`, stored from `start` in the tree's vertex arena.
fn polygon_node_at(vertices: &[DVec3], start: u32, input: u32, depth: u16, parent: u32) -> Node {
    let (normal, area) = newell(vertices);
    let centre = crate::formfactor::kernel::polygon_centroid(vertices);
    let radius = vertices
        .iter()
        .map(|v| v.distance(centre))
        .fold(0.0, f64::max);
    Node {
        parent,
        first_child: NONE,
        child_count: 0,
        kind: Kind::Polygon { input },
        vertex_start: start,
        vertex_count: vertices.len() as u32,
        leaves: (0, 0),
        area,
        vector_area: normal * area,
        facing: facing(normal, area),
        centre,
        radius,
        bounds: vertices
            .iter()
            .fold([DVec3::INFINITY, DVec3::NEG_INFINITY], |[lo, hi], v| {
                [lo.min(*v), hi.max(*v)]
            }),
        axis: normal,
        cone_cos: 1.0,
        depth,
        parts: split_count(vertices) as u8,
        plane_moment: plane_moment(vertices, centre, normal),
    }
}

/// A polygon node's children made by [`Tree::pieces`], before they enter the arena.
#[derive(Debug, Default)]
pub struct Pieces {
    nodes: Vec<Node>,
    vertices: Vec<DVec3>,
}

/// How a polygon node splits: a triangle or quad into four by its order-2 lattice (edge
/// midpoints), keeping its shape; an elongated one in two across its length, so that
/// slivers (a 100 m × 1 m corridor floor, a plank's 2 cm edge) become well-shaped
/// elements instead of thinner slivers, on which receiver points and affine fits lose
/// their accuracy: a quad whose opposite sides average more than [`LONG_QUAD`] times the
/// others by the lattice 2 × 1, a triangle whose longest edge exceeds [`LONG_TRIANGLE`]
/// times its height by that edge's midpoint; a larger convex polygon in two by the line
/// through its centroid across its longest extent. Midpoints are the lattice's, so
/// neighbours share them bit for bit.
pub fn split_polygon(vertices: &[DVec3]) -> Vec<Vec<DVec3>> {
    match split_shape(vertices) {
        Split::Quad { nu, nv } => crate::geometry::Lattice::Quad {
            corners: [vertices[0], vertices[1], vertices[2], vertices[3]],
            nu,
            nv,
        }
        .cell_polygons(),
        Split::Bisect(longest) => {
            let corners = [0, 1, 2].map(|k| vertices[(longest + k) % 3]);
            let middle = crate::geometry::Lattice::Triangle { corners, n: 2 }.point(1, 0);
            vec![
                vec![corners[0], middle, corners[2]],
                vec![middle, corners[1], corners[2]],
            ]
        }
        Split::Triangle => crate::geometry::subdivide(vertices, 2),
        Split::Halves => split_in_two(vertices),
    }
}

/// How many pieces [`split_polygon`] makes of `vertices`.
pub fn split_count(vertices: &[DVec3]) -> usize {
    match split_shape(vertices) {
        Split::Quad { nu, nv } => (nu * nv) as usize,
        Split::Triangle => 4,
        Split::Bisect(_) | Split::Halves => 2,
    }
}

/// The ways [`split_polygon`] splits.
enum Split {
    /// A quad by the lattice nu × nv.
    Quad { nu: u32, nv: u32 },
    /// A triangle into four similar ones.
    Triangle,
    /// A triangle in two at the midpoint of edge k (from vertex k).
    Bisect(usize),
    /// A larger polygon in two across its longest extent.
    Halves,
}

fn split_shape(vertices: &[DVec3]) -> Split {
    match vertices.len() {
        4 => {
            let side = |i: usize| vertices[i].distance(vertices[(i + 1) % 4]);
            let (along_u, along_v) = (side(0) + side(2), side(1) + side(3));
            if along_u > LONG_QUAD * along_v {
                Split::Quad { nu: 2, nv: 1 }
            } else if along_v > LONG_QUAD * along_u {
                Split::Quad { nu: 1, nv: 2 }
            } else {
                Split::Quad { nu: 2, nv: 2 }
            }
        }
        3 => {
            let (_, area) = newell(vertices);
            let side = |i: usize| vertices[i].distance(vertices[(i + 1) % 3]);
            let longest = (0..3)
                .max_by(|&a, &b| side(a).total_cmp(&side(b)))
                .unwrap_or(0);
            let length = side(longest);
            if length * length > LONG_TRIANGLE * 2.0 * area {
                Split::Bisect(longest)
            } else {
                Split::Triangle
            }
        }
        _ => Split::Halves,
    }
}

/// Splits a convex polygon into two convex halves by the line through its centroid
/// perpendicular to its longest vertex-to-vertex extent.
fn split_in_two(vertices: &[DVec3]) -> Vec<Vec<DVec3>> {
    let (normal, _) = newell(vertices);
    let centre = crate::formfactor::kernel::polygon_centroid(vertices);
    let mut dir = DVec3::X;
    let mut best = -1.0;
    for v in vertices {
        let d = *v - centre;
        if d.length_squared() > best {
            best = d.length_squared();
            dir = d;
        }
    }
    // Cut across the longest direction, within the polygon's plane.
    let cut = (dir - normal * dir.dot(normal)).normalize_or_zero();
    let halves = [cut, -cut]
        .into_iter()
        .filter_map(|c| crate::geometry::clip_to_halfspace(vertices, centre, c))
        .collect::<Vec<_>>();
    if halves.len() == 2 {
        halves
    } else {
        vec![vertices.to_vec()]
    }
}

/// The split of `items` (reordered in place) of least cost: returns the size of the left
/// part (1 ..= len − 1).
fn best_split<T: Copy>(
    items: &mut [T],
    get: impl Fn(&T) -> (DVec3, DVec3, DVec3, f64, DVec3),
) -> usize {
    let n = items.len();
    let (mut clo, mut chi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for it in items.iter() {
        let c = get(it).0;
        clo = clo.min(c);
        chi = chi.max(c);
    }
    #[derive(Clone, Copy)]
    struct Acc {
        lo: DVec3,
        hi: DVec3,
        count: usize,
        area: f64,
        vector_area: DVec3,
    }
    let empty = Acc {
        lo: DVec3::splat(f64::INFINITY),
        hi: DVec3::splat(f64::NEG_INFINITY),
        count: 0,
        area: 0.0,
        vector_area: DVec3::ZERO,
    };
    let add = |a: Acc, b: Acc| Acc {
        lo: a.lo.min(b.lo),
        hi: a.hi.max(b.hi),
        count: a.count + b.count,
        area: a.area + b.area,
        vector_area: a.vector_area + b.vector_area,
    };
    let cost = |a: &Acc| {
        if a.count == 0 {
            return 0.0;
        }
        let e = (a.hi - a.lo).max(DVec3::ZERO);
        let sa = e.x * e.y + e.y * e.z + e.z * e.x;
        let flatness = if a.area > 0.0 {
            a.vector_area.length() / a.area
        } else {
            1.0
        };
        sa.max(1e-300) * a.count as f64 * (1.0 + ORIENTATION_WEIGHT * (1.0 - flatness))
    };
    let item_acc = |it: &T| {
        let (_, lo, hi, area, normal) = get(it);
        Acc {
            lo,
            hi,
            count: 1,
            area,
            vector_area: normal * area,
        }
    };
    // Candidate: (cost, axis or 3 for orientation, bin boundary or sign axis).
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        let extent = chi[axis] - clo[axis];
        if extent <= 0.0 {
            continue;
        }
        let bin_of =
            |c: DVec3| (((c[axis] - clo[axis]) / extent * BINS as f64) as usize).min(BINS - 1);
        let mut bins = [empty; BINS];
        for it in items.iter() {
            let b = bin_of(get(it).0);
            bins[b] = add(bins[b], item_acc(it));
        }
        let mut right = [empty; BINS];
        let mut acc = empty;
        for b in (1..BINS).rev() {
            acc = add(acc, bins[b]);
            right[b] = acc;
        }
        let mut left = empty;
        for b in 1..BINS {
            left = add(left, bins[b - 1]);
            if left.count == 0 || right[b].count == 0 {
                continue;
            }
            let c = cost(&left) + cost(&right[b]);
            if best.is_none_or(|(bc, _, _)| c < bc) {
                best = Some((c, axis, b));
            }
        }
    }
    // Orientation split: by the sign of n·a along the axis of largest normal spread.
    let mut spread = DVec3::ZERO;
    for it in items.iter() {
        spread += get(it).4.abs();
    }
    let a = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    let (mut pos, mut neg) = (empty, empty);
    for it in items.iter() {
        if get(it).4[a] >= 0.0 {
            pos = add(pos, item_acc(it));
        } else {
            neg = add(neg, item_acc(it));
        }
    }
    if pos.count > 0 && neg.count > 0 {
        let c = cost(&pos) + cost(&neg);
        if best.is_none_or(|(bc, _, _)| c < bc) {
            best = Some((c, 3, a));
        }
    }
    let left = match best {
        Some((_, 3, a)) => partition(items, |it| get(it).4[a] >= 0.0),
        Some((_, axis, b)) => {
            let extent = chi[axis] - clo[axis];
            partition(items, |it| {
                let c = get(it).0;
                (((c[axis] - clo[axis]) / extent * BINS as f64) as usize).min(BINS - 1) < b
            })
        }
        None => 0,
    };
    if left == 0 || left == n {
        // All centroids equal and one orientation: halve by order (stable, deterministic).
        n / 2
    } else {
        left
    }
}

/// Moves the items for which `left` holds to the front (stable, O(n)); returns their count.
fn partition<T: Copy>(items: &mut [T], left: impl Fn(&T) -> bool) -> usize {
    let (l, r): (Vec<T>, Vec<T>) = items.iter().partition(|it| left(it));
    items[..l.len()].copy_from_slice(&l);
    items[l.len()..].copy_from_slice(&r);
    l.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn unit(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    fn node_of(members: &[(DVec3, f64)]) -> Node {
        let mut node = placeholder();
        for &(n, area) in members {
            for (f, g) in node.facing.iter_mut().zip(facing(n, area)) {
                *f += g;
            }
            node.area += area;
        }
        node
    }

    /// Slivers split across their length, everything else in four; the pieces tile the
    /// parent (areas add up, orientation kept) and their count is what `split_count` says.
    #[test]
    fn slivers_split_across_their_length() {
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let cases: [(Vec<DVec3>, usize); 5] = [
            (vec![v(0., 0.), v(1., 0.), v(1., 1.), v(0., 1.)], 4),
            (vec![v(0., 0.), v(10., 0.), v(10., 1.), v(0., 1.)], 2),
            (vec![v(0., 0.), v(1., 0.), v(1., 10.), v(0., 10.)], 2),
            (vec![v(0., 0.), v(1., 0.), v(0., 1.)], 4),
            (vec![v(0., 0.), v(10., 0.), v(5., 0.5)], 2),
        ];
        for (polygon, count) in cases {
            let (normal, area) = newell(&polygon);
            let pieces = split_polygon(&polygon);
            assert_eq!(pieces.len(), count, "{polygon:?}");
            assert_eq!(split_count(&polygon), count);
            let mut total = 0.0;
            let mut worst: f64 = 0.0;
            for piece in &pieces {
                let (n, a) = newell(piece);
                assert!(n.dot(normal) > 0.999, "{piece:?}");
                total += a;
                // Longest side over the area's square root: 1 for a square.
                let longest = (0..piece.len())
                    .map(|i| piece[i].distance(piece[(i + 1) % piece.len()]))
                    .fold(0.0, f64::max);
                worst = worst.max(longest / a.sqrt());
            }
            assert!((total - area).abs() < 1e-12 * area);
            let before = (0..polygon.len())
                .map(|i| polygon[i].distance(polygon[(i + 1) % polygon.len()]))
                .fold(0.0, f64::max)
                / area.sqrt();
            if count == 2 {
                assert!(worst < 0.75 * before, "{worst} vs {before}");
            }
        }
    }

    #[test]
    fn projected_bound_is_exact_for_a_box_seen_along_an_axis_or_a_diagonal() {
        // A 1 × 2 × 3 box: faces ±x of area 6, ±y of 3, ±z of 2.
        let faces = [
            (DVec3::X, 6.0),
            (-DVec3::X, 6.0),
            (DVec3::Y, 3.0),
            (-DVec3::Y, 3.0),
            (DVec3::Z, 2.0),
            (-DVec3::Z, 2.0),
        ];
        let node = node_of(&faces);
        assert!((node.projected_bound(DVec3::X, 0.0) - 6.0).abs() < 1e-12);
        assert!((node.projected_bound(-DVec3::Z, 0.0) - 2.0).abs() < 1e-12);
        // Seen along (1, 1, 1)/√3 a box shows three faces: (6 + 3 + 2)/√3.
        let w = DVec3::ONE.normalize();
        let exact = 11.0 / 3f64.sqrt();
        assert!((node.projected_bound(w, 0.0) - exact).abs() < 1e-12);
        // Never more than the area, however wide the cone.
        assert!(node.projected_bound(w, PI) <= node.area);
    }

    proptest! {
        /// For any set of one-sided polygons and any cone of directions, the bound is at
        /// least the projected area Σ A_i max(0, n_i · w) at every direction w of the cone
        /// (checked on five rings from the axis to the rim, 16 directions each).
        #[test]
        fn projected_bound_bounds_every_direction_of_the_cone(
            members in proptest::collection::vec((0.0..PI, 0.0..2.0 * PI, 0.01f64..2.0), 1..12),
            axis in (0.0..PI, 0.0..2.0 * PI),
            spread in 0.0..1.5f64,
        ) {
            let members: Vec<(DVec3, f64)> =
                members.iter().map(|&(t, f, a)| (unit(t, f), a)).collect();
            let node = node_of(&members);
            let toward = unit(axis.0, axis.1);
            let bound = node.projected_bound(toward, spread);
            let (u, v) = toward.any_orthonormal_pair();
            for ring in 0..=4 {
                let angle = spread * ring as f64 / 4.0;
                for k in 0..16 {
                    let phi = 2.0 * PI * k as f64 / 16.0;
                    let w = toward * angle.cos() + (u * phi.cos() + v * phi.sin()) * angle.sin();
                    let projected: f64 =
                        members.iter().map(|&(n, a)| a * n.dot(w).max(0.0)).sum();
                    prop_assert!(projected <= bound * (1.0 + 1e-12) + 1e-12);
                }
            }
        }
    }
}

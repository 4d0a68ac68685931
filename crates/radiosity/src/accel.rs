//! Ray casting against triangles: a bounding volume hierarchy for visibility queries.
//!
//! The form-factor stage asks two questions millions of times: "is the segment between these
//! two points blocked?" ([`Bvh::segment_occluded`], [`Bvh::occluded`]) and "what does this ray
//! hit first?" ([`Bvh::intersect`]). Both are answered by a BVH over the scene's triangles.
//!
//! Build: a binary tree by the binned surface area heuristic (Wald 2007, "On fast Construction
//! of SAH-based Bounding Volume Hierarchies"): a node's split minimises
//! `C_trav + (A_left·P_left + A_right·P_right) / A_node` over 16 candidate planes per axis,
//! where `A` is surface area and `P` counts packets of four triangles (tested together), and a
//! node becomes a leaf when that is no cheaper than testing its own packets. The binary tree is
//! then collapsed into a 4-wide one (each node adopts its children's children, largest first),
//! as in Embree (Wald et al. 2014).
//!
//! Layout, chosen because incoherent rays are bound by memory latency and branch misses: a
//! 4-wide node is two cache lines holding its four children's boxes transposed (one SIMD slab
//! test checks all four, 32 bytes per child); leaves are runs of 4-triangle packets, stored
//! contiguously in leaf order with coordinates transposed for SIMD. Measured on the
//! 100k-triangle Cornell box of `benches/bvh.rs`, one thread: binary nodes (32 bytes, siblings
//! in one cache line) with one triangle per test cast 1.0–1.2 M shadow rays/s, with packets
//! 1.3 M/s, and 4-wide nodes with packets 2.1 M/s.
//!
//! Triangles are double-sided. The ray-triangle test is the watertight test of Woop, Benthin &
//! Wald 2013 ("Watertight Ray/Triangle Intersection", JCGT 2(1)): a ray through an edge or vertex
//! shared by two triangles (with bit-identical vertex coordinates) hits at least one of them.
//! Box tests follow Ize 2013 ("Robust BVH Ray Traversal") to stay conservative under rounding.
//!
//! Lengths are in the scene's unit (metres); ray parameters `t` are in units of the ray's
//! direction vector, which need not be normalised.
//!
//! See also: the form-factor stage, which is the main caller.

use glam::{DVec3, Vec3, Vec3A, Vec4};

/// Triangles tested together by one SIMD ray-triangle test.
const PACKET: usize = 4;
/// Candidate split planes per axis are the boundaries between this many bins.
const BINS: usize = 16;
/// Leaves never hold more triangles than this (four packets).
const MAX_LEAF: usize = 16;
/// Below this depth nodes are split by plain halving, not the SAH, so that pathological inputs
/// (triangles spaced exponentially, say) cannot make the tree arbitrarily deep.
const MAX_SAH_DEPTH: usize = 32;
/// Traversal stack size for any tree: a node pushes at most three children, and halving at
/// most 2²⁹ triangles down to one packet takes fewer than 32 levels below `MAX_SAH_DEPTH`.
const STACK: usize = 3 * (MAX_SAH_DEPTH + 32) + 1;
/// Trees at most this deep (in 4-wide nodes; typical ones have 8–12 levels) get a smaller
/// stack.
const SHALLOW_DEPTH: usize = 16;
/// Bits of a child reference holding a leaf's packet count (0 marks an inner node).
const COUNT_BITS: u32 = 3;
const _: () = assert!(MAX_LEAF.div_ceil(PACKET) < 1 << COUNT_BITS);
/// Cost of one traversal step relative to one packet test, for the SAH. Measured: 2–6 are
/// equally good on a 100k-triangle Cornell box; 1 (small leaves) is 10–20 % slower.
const TRAVERSAL_COST: f32 = 3.0;
/// Subtrees with more triangles than this are built on separate rayon tasks.
const PARALLEL_BUILD: usize = 8192;
/// Relative widening `2γ₃` of a box's entry and exit distances (Ize 2013), so that rounding
/// never culls a true hit.
const ROBUST_WIDEN: f32 = 2.0 * 3.0 * f32::EPSILON * 0.5 / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// The BVH packet (four triangles) that blocked the latest of a run of shadow rays, tried
/// first by the next ([`Bvh::occluded_trying`]): the rays between two patches are often
/// blocked by the same triangles. Not shared between threads.
#[derive(Debug)]
pub struct Blocker(std::cell::Cell<u32>);

impl Default for Blocker {
    /// No packet yet.
    fn default() -> Self {
        Blocker(std::cell::Cell::new(u32::MAX))
    }
}

/// Subtrees of a [`Bvh`] that together hold every triangle a capsule may hold (from
/// [`Bvh::capsule_subtrees`]): a ray inside the capsule meets what it would meet in the
/// whole tree by traversing these alone ([`Bvh::occluded_in_trying`]), without the descent
/// from the root to them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Subtrees(Vec<Child>);

/// The most subtrees [`Bvh::capsule_subtrees`] lists. Measured on the furnished rooms'
/// links whose shafts hold too many triangles to list (`perf stat`, task-clock, against
/// traversing from the root): 1000 objects 3–5 % less CPU with 4, 2 % with 8, 4–5 % more
/// with 16 (each listed subtree the ray enters costs a node test); 3000 objects 6.5 % less
/// with 4.
pub const MOST_SUBTREES: usize = 4;

/// Where a ray first meets the scene: the answer of [`Bvh::intersect`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: the point is `origin + t * dir`.
    pub t: f32,
    /// Index of the triangle in the slice given to [`Bvh::build`].
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex; the point is `(1-u-v)·v0 + u·v1 + v·v2`.
    pub v: f32,
}

/// Bounding volume hierarchy over triangles (binned SAH build), for shadow rays and closest hits.
///
/// Immutable once built, `Send + Sync`: share one `&Bvh` between rayon threads. Memory: about
/// 45 bytes per triangle (the input is not kept).
///
/// See also: [`Hit`], [`Bvh::segment_occluded`].
#[derive(Clone)]
pub struct Bvh {
    /// The root, which may be a leaf, and its box; every stored node has two to four children.
    root: Child,
    bounds: Aabb,
    nodes: Vec<Node>,
    /// Leaves' triangles, in leaf order.
    packets: Vec<Packet>,
    /// Input index of each lane of `packets`.
    ids: Vec<[u32; PACKET]>,
    /// Number of input triangles.
    len: usize,
    /// Inner nodes on the longest path from the root to a leaf.
    depth: usize,
}

/// A reference to a node or a leaf, packed in 32 bits: `first << COUNT_BITS | count`, where a
/// leaf is `count` (1 to 7) packets from `Bvh::packets[first]`, and `count` 0 marks an inner
/// node `Bvh::nodes[first]`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Child(u32);

impl Child {
    fn leaf(first: usize, count: usize) -> Self {
        debug_assert!((1..1 << COUNT_BITS).contains(&count));
        Child((first as u32) << COUNT_BITS | count as u32)
    }

    fn inner(index: usize) -> Self {
        Child((index as u32) << COUNT_BITS)
    }

    #[inline(always)]
    fn count(self) -> usize {
        (self.0 & ((1 << COUNT_BITS) - 1)) as usize
    }

    #[inline(always)]
    fn first(self) -> usize {
        (self.0 >> COUNT_BITS) as usize
    }
}

/// A 4-wide node: its children's boxes, transposed so that one SIMD slab test checks all four.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct Node {
    /// `bounds[0][axis]` holds the four children's minima along `axis`, `bounds[1]` maxima.
    bounds: [[Vec4; 3]; 2],
    children: [Child; 4],
    /// Bit `i` set when child slot `i` is used.
    used: u32,
}

/// Four triangles, transposed: `v[vertex][axis]` holds one coordinate of one vertex of each
/// (lanes). A leaf whose size is not a multiple of four repeats its last triangle.
#[derive(Debug, Clone, Copy)]
struct Packet {
    v: [[Vec4; 3]; 3],
}

impl Packet {
    fn new(tris: [&[Vec3; 3]; PACKET]) -> Self {
        let lanes = |vertex: usize, axis: usize| Vec4::from(tris.map(|t| t[vertex][axis]));
        Packet {
            v: [0, 1, 2].map(|vertex| [0, 1, 2].map(|axis| lanes(vertex, axis))),
        }
    }
}

impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh")
            .field("triangles", &self.len)
            .field("packets", &self.packets.len())
            .field("nodes", &self.nodes.len())
            .finish()
    }
}

impl Bvh {
    /// Builds the hierarchy over `triangles` (binned SAH, in parallel for large inputs).
    ///
    /// An empty slice gives a hierarchy that nothing hits. Degenerate (zero-area) triangles are
    /// accepted and never hit. Triangles with non-finite coordinates are accepted, but rays
    /// near them may or may not report them.
    ///
    /// # Panics
    /// If there are more than 2²⁹ (about 537 million) triangles.
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        use rayon::prelude::*;
        assert!(
            triangles.len() <= 1 << (32 - COUNT_BITS),
            "a BVH holds at most 2^29 triangles"
        );
        let mut bvh = Bvh {
            root: Child::default(),
            bounds: Aabb::EMPTY,
            nodes: Vec::new(),
            packets: Vec::new(),
            ids: Vec::new(),
            len: triangles.len(),
            depth: 0,
        };
        if triangles.is_empty() {
            return bvh;
        }
        let mut prims: Vec<Prim> = triangles
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(i, t)| Prim::new(i as u32, t))
            .collect();
        let tree = build_node(&mut prims, 0, 0);
        let order: Vec<u32> = prims.iter().map(|p| p.id).collect();
        drop(prims);
        bvh.nodes.reserve(triangles.len() / 8);
        bvh.packets.reserve(triangles.len() / 3);
        bvh.ids.reserve(triangles.len() / 3);
        bvh.bounds = *tree.bounds();
        (bvh.root, bvh.depth) = bvh.flatten(&tree, triangles, &order);
        bvh
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when built from no triangles: nothing is ever hit.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Any hit with `t` in the open interval `(t_min, t_max)` along `origin + t * dir`?
    ///
    /// `dir` need not be normalised; a zero or non-finite `dir` hits nothing. Stops at the first
    /// hit found, which is not necessarily the closest.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
        self.occluded_trying(origin, dir, t_min, t_max, &Blocker::default())
    }

    /// [`Bvh::occluded`], trying the packet of `blocker` before the traversal and leaving
    /// in it the packet that blocked this ray, if one did: the same answer, found without a
    /// traversal where the rays of a run are blocked by the same triangles.
    pub fn occluded_trying(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocker: &Blocker,
    ) -> bool {
        self.occluded_from_roots(&[self.root], origin, dir, t_min, t_max, blocker)
    }

    /// [`Bvh::occluded_trying`] for a ray inside the capsule that `subtrees` were listed for
    /// ([`Bvh::capsule_subtrees`]): the same answer, traversing those subtrees alone.
    pub fn occluded_in_trying(
        &self,
        subtrees: &Subtrees,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocker: &Blocker,
    ) -> bool {
        self.occluded_from_roots(&subtrees.0, origin, dir, t_min, t_max, blocker)
    }

    /// [`Bvh::occluded_trying`] below `roots` (the root, or subtrees holding every triangle
    /// the ray can meet).
    fn occluded_from_roots(
        &self,
        roots: &[Child],
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        blocker: &Blocker,
    ) -> bool {
        let Some(ray) = Ray::new(origin, dir) else {
            return false;
        };
        let nonempty_range = t_min < t_max; // false when either is NaN
        if self.is_empty()
            || roots.is_empty()
            || !nonempty_range
            || ray.enter(&self.bounds, t_min, t_max).is_none()
        {
            return false;
        }
        let range = (Vec4::splat(t_min), Vec4::splat(t_max));
        if let Some(packet) = self.packets.get(blocker.0.get() as usize) {
            if ray.hit(packet, range).0 != 0 {
                return true;
            }
        }
        self.occluded_below(&ray, range, roots, blocker)
    }

    /// Whether the ray hits a triangle below `roots` (at most [`MOST_SUBTREES`]) within
    /// `range`, leaving the packet that blocked it in `blocker`.
    fn occluded_below(
        &self,
        ray: &Ray,
        range: (Vec4, Vec4),
        roots: &[Child],
        blocker: &Blocker,
    ) -> bool {
        // A stack sized for the tree at hand: zeroing a larger one costs 4 % of the ray's time.
        let hit = if self.depth <= SHALLOW_DEPTH {
            self.occluded_from::<{ 3 * SHALLOW_DEPTH + 1 + MOST_SUBTREES }>(ray, range, roots)
        } else {
            self.occluded_from::<STACK>(ray, range, roots)
        };
        if let Some(k) = hit {
            blocker.0.set(k as u32);
        }
        hit.is_some()
    }

    /// The packet of some triangle the ray hits within `range` below `roots` (one to
    /// [`MOST_SUBTREES`] of them), after the checks of [`Bvh::occluded_trying`], with a
    /// traversal stack of `N` entries.
    fn occluded_from<const N: usize>(
        &self,
        ray: &Ray,
        range: (Vec4, Vec4),
        roots: &[Child],
    ) -> Option<usize> {
        let mut stack = [Child::default(); N];
        let (&first, rest) = roots.split_first()?;
        stack[..rest.len()].copy_from_slice(rest);
        let mut top = rest.len();
        let mut child = first;
        loop {
            if child.count() > 0 {
                let leaf = child.first()..child.first() + child.count();
                if let Some(k) = leaf
                    .into_iter()
                    .find(|&k| ray.hit(&self.packets[k], range).0 != 0)
                {
                    return Some(k);
                }
            } else {
                let node = &self.nodes[child.first()];
                let (mut hits, _) = ray.enter_node(node, range);
                if hits != 0 {
                    // Any blocker will do, so children are taken in slot order: visiting the
                    // nearest first (as `intersect` does) measured 4 % slower here.
                    child = node.children[hits.trailing_zeros() as usize];
                    hits &= hits - 1;
                    while hits != 0 {
                        stack[top] = node.children[hits.trailing_zeros() as usize];
                        top += 1;
                        hits &= hits - 1;
                    }
                    continue;
                }
            }
            if top == 0 {
                return None;
            }
            top -= 1;
            child = stack[top];
        }
    }

    /// Closest hit with `t` in the open interval `(t_min, t_max)` along `origin + t * dir`.
    ///
    /// `dir` need not be normalised; a zero or non-finite `dir` hits nothing. Ties between
    /// triangles at exactly the same `t` go to either.
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let ray = Ray::new(origin, dir)?;
        let nonempty_range = t_min < t_max; // false when either is NaN
        if self.is_empty() || !nonempty_range {
            return None;
        }
        ray.enter(&self.bounds, t_min, t_max)?;
        let range = (Vec4::splat(t_min), Vec4::splat(t_max));
        if self.depth <= SHALLOW_DEPTH {
            self.intersect_from::<{ 3 * SHALLOW_DEPTH + 1 }>(&ray, range)
        } else {
            self.intersect_from::<STACK>(&ray, range)
        }
    }

    /// `intersect` after the checks, with a traversal stack of `N` entries.
    fn intersect_from<const N: usize>(&self, ray: &Ray, mut range: (Vec4, Vec4)) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        // Pending far children with their entry distance, to skip those beyond a closer hit.
        let mut stack = [(Child::default(), 0f32); N];
        let mut top = 0;
        let mut child = self.root;
        loop {
            if child.count() > 0 {
                let (start, end) = (child.first(), child.first() + child.count());
                for (packet, ids) in self.packets[start..end].iter().zip(&self.ids[start..end]) {
                    let (mut lanes, t, u, v) = ray.hit(packet, range);
                    while lanes != 0 {
                        let lane = lanes.trailing_zeros() as usize;
                        lanes &= lanes - 1;
                        if t[lane] < range.1.x {
                            range.1 = Vec4::splat(t[lane]);
                            best = Some(Hit {
                                t: t[lane],
                                triangle: ids[lane],
                                u: u[lane],
                                v: v[lane],
                            });
                        }
                    }
                }
            } else {
                let node = &self.nodes[child.first()];
                let (mut hits, enter) = ray.enter_node(node, range);
                if hits != 0 {
                    // Push the farther children farthest first, so that they pop nearest first.
                    let base = top;
                    while hits != 0 {
                        let lane = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        let mut at = top;
                        while at > base && stack[at - 1].1 < enter[lane] {
                            stack[at] = stack[at - 1];
                            at -= 1;
                        }
                        stack[at] = (node.children[lane], enter[lane]);
                        top += 1;
                    }
                    top -= 1;
                    child = stack[top].0;
                    continue;
                }
            }
            loop {
                if top == 0 {
                    return best;
                }
                top -= 1;
                let (next, enter) = stack[top];
                if enter < range.1.x {
                    child = next;
                    break;
                }
            }
        }
    }

    /// Is the open segment `a`–`b` blocked by any triangle?
    ///
    /// Hits within `eps` of either end, as a fraction of the segment's length (1e-4 is typical),
    /// are ignored, so the triangles the end points lie on do not block. A zero-length segment
    /// is never blocked.
    pub fn segment_occluded(&self, a: Vec3, b: Vec3, eps: f32) -> bool {
        self.occluded(a, b - a, eps, 1.0 - eps)
    }

    /// [`Bvh::segment_occluded`] against the triangles of `packets` alone (indices from
    /// [`Bvh::capsule_visit`]): the same ray–triangle test, without the traversal. When every
    /// triangle that could cross the segment is in `packets`, the answer is the same.
    pub fn segment_occluded_among(&self, packets: &[u32], a: Vec3, b: Vec3, eps: f32) -> bool {
        self.segment_occluded_among_trying(packets, a, b, eps, &Blocker::default())
    }

    /// [`Bvh::segment_occluded_among`], trying the packet of `blocker` first and leaving in
    /// it the packet that blocked this segment, if one did. The same answer when the
    /// blocker's packet is one of `packets` (or none): with the same rays of one shaft.
    pub fn segment_occluded_among_trying(
        &self,
        packets: &[u32],
        a: Vec3,
        b: Vec3,
        eps: f32,
        blocker: &Blocker,
    ) -> bool {
        let Some(ray) = ShearedRay::new(a, b - a) else {
            return false;
        };
        let range = (Vec4::splat(eps), Vec4::splat(1.0 - eps));
        if let Some(packet) = self.packets.get(blocker.0.get() as usize) {
            if ray.hit(packet, range).0 != 0 {
                return true;
            }
        }
        match packets
            .iter()
            .find(|&&k| ray.hit(&self.packets[k as usize], range).0 != 0)
        {
            Some(&k) => {
                blocker.0.set(k);
                true
            }
            None => false,
        }
    }

    /// Calls `visit(packet, triangle, vertices)` for every triangle that may lie within
    /// distance `radius` of the segment `a`–`b` (a capsule holding the convex hull of two
    /// spheres of at most that radius about the ends: a conservative shaft; boxes and
    /// triangles are tested by their bounding spheres, so a triangle not visited certainly
    /// lies outside, a visited one only possibly inside), `packet` the index of the group of
    /// triangles it is stored in (for
    /// [`Bvh::segment_occluded_among`]), until `visit` returns true; returns whether it did.
    /// The triangles of one packet are visited one after another. With `clip` = [lo, hi],
    /// only triangles whose bounding box overlaps that box are visited, and subtrees
    /// outside it are not walked. Triangles that `cull` rules out are not visited.
    pub fn capsule_visit(
        &self,
        a: Vec3,
        b: Vec3,
        radius: f32,
        clip: Option<[Vec3; 2]>,
        cull: &Cull,
        visit: &mut dyn FnMut(u32, u32, &[Vec3; 3]) -> bool,
    ) -> bool {
        let near = Capsule::new(a, b, radius, clip);
        if self.len == 0 || !near.holds(self.bounds.min.into(), self.bounds.max.into()) {
            return false;
        }
        let mut stack = vec![self.root];
        while let Some(child) = stack.pop() {
            if child.count() > 0 {
                if (child.first()..child.first() + child.count())
                    .any(|k| self.packet_visit(k, &near, cull, visit))
                {
                    return true;
                }
            } else {
                let node = &self.nodes[child.first()];
                let mut held = near.holds4(node.bounds[0], node.bounds[1]) & node.used;
                while held != 0 {
                    stack.push(node.children[held.trailing_zeros() as usize]);
                    held &= held - 1;
                }
            }
        }
        false
    }

    /// At most `most` (≤ [`MOST_SUBTREES`]) subtrees that hold every triangle the capsule
    /// of [`Bvh::capsule_visit`] may hold: nodes the capsule may hold are opened breadth
    /// first, each replaced by its children that the capsule may hold, while the list stays
    /// within `most`. Empty when the capsule holds nothing.
    pub fn capsule_subtrees(
        &self,
        a: Vec3,
        b: Vec3,
        radius: f32,
        clip: Option<[Vec3; 2]>,
        most: usize,
    ) -> Subtrees {
        let most = most.clamp(1, MOST_SUBTREES);
        let near = Capsule::new(a, b, radius, clip);
        if self.len == 0 || !near.holds(self.bounds.min.into(), self.bounds.max.into()) {
            return Subtrees::default();
        }
        let mut list = vec![self.root];
        let mut opened = true;
        while opened {
            opened = false;
            let mut next = Vec::with_capacity(most);
            for (i, &child) in list.iter().enumerate() {
                if child.count() == 0 {
                    let node = &self.nodes[child.first()];
                    let mut held = near.holds4(node.bounds[0], node.bounds[1]) & node.used;
                    let after = list.len() - i - 1;
                    if next.len() + held.count_ones() as usize + after <= most {
                        while held != 0 {
                            next.push(node.children[held.trailing_zeros() as usize]);
                            held &= held - 1;
                        }
                        opened = true;
                        continue;
                    }
                }
                next.push(child);
            }
            list = next;
        }
        Subtrees(list)
    }

    /// [`Bvh::capsule_visit`] over the triangles of `packets` alone (indices it gave): for a
    /// capsule and box inside those of the visit that listed them, the same triangles
    /// without the traversal.
    #[allow(clippy::too_many_arguments)]
    pub fn capsule_visit_among(
        &self,
        packets: &[u32],
        a: Vec3,
        b: Vec3,
        radius: f32,
        clip: Option<[Vec3; 2]>,
        cull: &Cull,
        visit: &mut dyn FnMut(u32, u32, &[Vec3; 3]) -> bool,
    ) -> bool {
        let near = Capsule::new(a, b, radius, clip);
        packets
            .iter()
            .any(|&k| self.packet_visit(k as usize, &near, cull, visit))
    }

    /// Calls `visit(k, triangle, vertices)` for each triangle of packet `k` (once each) that
    /// may lie in `near` and that `cull` does not rule out, until it returns true; returns
    /// whether it did.
    fn packet_visit(
        &self,
        k: usize,
        near: &Capsule,
        cull: &Cull,
        visit: &mut dyn FnMut(u32, u32, &[Vec3; 3]) -> bool,
    ) -> bool {
        let v = &self.packets[k].v;
        let min = [0, 1, 2].map(|a| v[0][a].min(v[1][a]).min(v[2][a]));
        let max = [0, 1, 2].map(|a| v[0][a].max(v[1][a]).max(v[2][a]));
        let mut held = near.holds4(min, max);
        if held != 0 {
            held &= !cull.behind(&self.packets[k]);
        }
        held != 0
            && self
                .packet_triangles(k)
                .any(|(lane, id, tri)| held & (1 << lane) != 0 && visit(k as u32, id, &tri))
    }

    /// The triangles of packet `k`, once each (a leaf pads its last packet with its last
    /// triangle), as (lane, input index, vertices).
    fn packet_triangles(&self, k: usize) -> impl Iterator<Item = (usize, u32, [Vec3; 3])> + '_ {
        let (packet, ids) = (&self.packets[k], self.ids[k]);
        (0..PACKET)
            .filter(move |&lane| lane == 0 || ids[lane] != ids[lane - 1])
            .map(move |lane| {
                let tri = [0, 1, 2].map(|v| {
                    Vec3::new(
                        packet.v[v][0][lane],
                        packet.v[v][1][lane],
                        packet.v[v][2][lane],
                    )
                });
                (lane, ids[lane], tri)
            })
    }

    /// Appends to `out` every triangle whose bounding box overlaps the box [`lo`, `hi`], as
    /// (input index, vertices); `out` is cleared first. Each triangle appears once.
    pub fn triangles_in_box(&self, lo: Vec3, hi: Vec3, out: &mut Vec<(u32, [Vec3; 3])>) {
        out.clear();
        let overlaps = |min: Vec3, max: Vec3| min.cmple(hi).all() && max.cmpge(lo).all();
        if self.len == 0 || !overlaps(self.bounds.min.into(), self.bounds.max.into()) {
            return;
        }
        let mut stack = vec![self.root];
        while let Some(child) = stack.pop() {
            if child.count() > 0 {
                for k in child.first()..child.first() + child.count() {
                    for (_, id, tri) in self.packet_triangles(k) {
                        let (tmin, tmax) = (
                            tri[0].min(tri[1]).min(tri[2]),
                            tri[0].max(tri[1]).max(tri[2]),
                        );
                        if overlaps(tmin, tmax) {
                            out.push((id, tri));
                        }
                    }
                }
            } else {
                let node = &self.nodes[child.first()];
                for slot in 0..4 {
                    if node.used & (1 << slot) == 0 {
                        continue;
                    }
                    let min = Vec3::new(
                        node.bounds[0][0][slot],
                        node.bounds[0][1][slot],
                        node.bounds[0][2][slot],
                    );
                    let max = Vec3::new(
                        node.bounds[1][0][slot],
                        node.bounds[1][1][slot],
                        node.bounds[1][2][slot],
                    );
                    if overlaps(min, max) {
                        stack.push(node.children[slot]);
                    }
                }
            }
        }
    }

    /// Appends `node` to the 4-wide tree: its node before its descendants, its leaves'
    /// triangles to `packets`. Returns the reference to it and its depth in inner nodes.
    fn flatten(
        &mut self,
        node: &BuildNode,
        triangles: &[[Vec3; 3]],
        order: &[u32],
    ) -> (Child, usize) {
        match node {
            BuildNode::Leaf { first, count, .. } => {
                let start = self.packets.len();
                let leaf = &order[*first as usize..(*first + *count) as usize];
                for chunk in leaf.chunks(PACKET) {
                    let ids: [u32; PACKET] =
                        std::array::from_fn(|lane| chunk[lane.min(chunk.len() - 1)]);
                    self.packets
                        .push(Packet::new(ids.map(|i| &triangles[i as usize])));
                    self.ids.push(ids);
                }
                (Child::leaf(start, self.packets.len() - start), 0)
            }
            BuildNode::Inner { children, .. } => {
                // Adopt grandchildren, largest box first, until there are four children.
                let mut adopted: Vec<&BuildNode> = children.iter().collect();
                while adopted.len() < 4 {
                    let largest = adopted
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| matches!(c, BuildNode::Inner { .. }))
                        .max_by(|(_, a), (_, b)| {
                            a.bounds().half_area().total_cmp(&b.bounds().half_area())
                        })
                        .map(|(i, _)| i);
                    let Some(i) = largest else { break };
                    let BuildNode::Inner { children, .. } = adopted[i] else {
                        unreachable!("filtered on Inner")
                    };
                    adopted.splice(i..=i, children.iter());
                }
                let index = self.nodes.len();
                self.nodes.push(Node {
                    bounds: [[Vec4::ZERO; 3]; 2],
                    children: [Child::default(); 4],
                    used: 0,
                });
                let mut node = self.nodes[index];
                let mut depth = 0;
                for (slot, c) in adopted.into_iter().enumerate() {
                    let b = c.bounds();
                    for axis in 0..3 {
                        node.bounds[0][axis][slot] = b.min[axis];
                        node.bounds[1][axis][slot] = b.max[axis];
                    }
                    let (child, child_depth) = self.flatten(c, triangles, order);
                    node.children[slot] = child;
                    node.used |= 1 << slot;
                    depth = depth.max(child_depth);
                }
                self.nodes[index] = node;
                (Child::inner(index), depth + 1)
            }
        }
    }
}

/// A ray with what every box and triangle test needs precomputed.
struct Ray {
    origin: Vec3A,
    /// `1 / dir`, with zeros replaced by huge values of the same sign so no NaN arises.
    inv_dir: Vec3A,
    /// `origin` and `inv_dir`, each coordinate splatted over four lanes.
    origin_4: [Vec4; 3],
    inv_dir_4: [Vec4; 3],
    /// Per axis, which of a box's planes the ray meets first: 0 the minimum, 1 the maximum.
    near_side: [usize; 3],
    /// The triangle test's part.
    sheared: ShearedRay,
}

/// What the watertight triangle test ([`ShearedRay::hit`]) needs of a ray, alone: a segment
/// tested against a shaft's listed packets walks no boxes ([`Bvh::segment_occluded_among`]),
/// so it skips the reciprocal and the splats those need.
struct ShearedRay {
    /// Axes permuted so that `kz` is the direction's dominant one (`[kx, ky, kz]`).
    axes: [usize; 3],
    /// The origin's coordinate along `kx`, `ky`, `kz`, splatted.
    origin_k: [Vec4; 3],
    /// Shear taking the ray to the +z axis: `dir[kx]/dir[kz]`, `dir[ky]/dir[kz]`, `1/dir[kz]`,
    /// splatted.
    shear: [Vec4; 3],
}

/// Planes a capsule visit looks past ([`Bvh::capsule_visit`]): a triangle lying wholly on or
/// behind one of them, every vertex v at (v − origin) · normal ≤ `on_plane` (the distance in
/// f32, as `Vec3::dot` gives it, compared in f64), is not visited. Four triangles at a time,
/// lane by lane the same operations as one at a time (a test in the visitor before: 10 % of
/// a furnished room's CPU in the visitor and its calls).
#[derive(Debug, Clone, Copy, Default)]
pub struct Cull {
    /// Up to two planes, each as (a point on it, its unit normal).
    pub planes: [Option<(Vec3, Vec3)>; 2],
    /// How far above a plane a vertex may lie and still count as on it, m.
    pub on_plane: f64,
}

impl Cull {
    /// The lanes of `packet` whose triangles lie wholly on or behind one of the planes.
    #[inline]
    fn behind(&self, packet: &Packet) -> u32 {
        let mut mask = 0;
        for &(origin, normal) in self.planes.iter().flatten() {
            let mut all = (1 << PACKET) - 1;
            for vertex in &packet.v {
                let distance = (vertex[0] - Vec4::splat(origin.x)) * Vec4::splat(normal.x)
                    + (vertex[1] - Vec4::splat(origin.y)) * Vec4::splat(normal.y)
                    + (vertex[2] - Vec4::splat(origin.z)) * Vec4::splat(normal.z);
                let distance = distance.to_array();
                all &= (0..PACKET).fold(0, |m, lane| {
                    m | u32::from(f64::from(distance[lane]) <= self.on_plane) << lane
                });
            }
            mask |= all;
        }
        mask
    }
}

/// The conservative test of [`Bvh::capsule_visit`]: whether a box may reach within `radius`
/// of the segment `a`–`b` (by its bounding sphere) and overlaps `clip`.
struct Capsule {
    a: Vec3,
    seg: Vec3,
    len2: f32,
    radius: f32,
    clip: Option<[Vec3; 2]>,
}

impl Capsule {
    fn new(a: Vec3, b: Vec3, radius: f32, clip: Option<[Vec3; 2]>) -> Self {
        let seg = b - a;
        Capsule {
            a,
            seg,
            len2: seg.length_squared(),
            radius,
            clip,
        }
    }

    /// Whether the box [`min`, `max`] may hold points of the capsule.
    #[inline]
    fn holds(&self, min: Vec3, max: Vec3) -> bool {
        if let Some([lo, hi]) = self.clip {
            if min.cmpgt(hi).any() || max.cmplt(lo).any() {
                return false;
            }
        }
        let centre = (min + max) * 0.5;
        let t = if self.len2 > 0.0 {
            ((centre - self.a).dot(self.seg) / self.len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (self.a + self.seg * t).distance(centre) <= self.radius + (max - min).length() * 0.5
    }

    /// [`Capsule::holds`] for four boxes at once, their corners transposed (`min[axis]`
    /// holds one coordinate of each box's minimum): the mask of those it may hold. The same
    /// operations in the same order, lane by lane, so the same answers.
    #[inline]
    fn holds4(&self, min: [Vec4; 3], max: [Vec4; 3]) -> u32 {
        let mut outside = 0;
        if let Some([lo, hi]) = self.clip {
            for a in 0..3 {
                outside |= min[a].cmpgt(Vec4::splat(hi[a])).bitmask()
                    | max[a].cmplt(Vec4::splat(lo[a])).bitmask();
            }
        }
        let centre = [0, 1, 2].map(|a| (min[a] + max[a]) * 0.5);
        let (a, seg) = (
            [0, 1, 2].map(|k| Vec4::splat(self.a[k])),
            [0, 1, 2].map(|k| Vec4::splat(self.seg[k])),
        );
        let t = if self.len2 > 0.0 {
            let along = (centre[0] - a[0]) * seg[0]
                + (centre[1] - a[1]) * seg[1]
                + (centre[2] - a[2]) * seg[2];
            // As `f32::clamp` lane by lane (a NaN stays NaN: the lane is not held).
            let t = along / Vec4::splat(self.len2);
            Vec4::select(
                t.cmplt(Vec4::ZERO),
                Vec4::ZERO,
                Vec4::select(t.cmpgt(Vec4::ONE), Vec4::ONE, t),
            )
        } else {
            Vec4::ZERO
        };
        let d = [0, 1, 2].map(|k| a[k] + seg[k] * t - centre[k]);
        let distance = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let e = [0, 1, 2].map(|k| max[k] - min[k]);
        let half_diagonal = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt() * 0.5;
        distance
            .cmple(Vec4::splat(self.radius) + half_diagonal)
            .bitmask()
            & !outside
    }
}

impl Ray {
    fn new(origin: Vec3, dir: Vec3) -> Option<Self> {
        let sheared = ShearedRay::new(origin, dir)?;
        let inv = dir.recip();
        let inv_dir = Vec3::select(
            inv.is_finite_mask(),
            inv,
            Vec3::splat(f32::MAX).copysign(dir),
        );
        Some(Ray {
            origin: origin.into(),
            inv_dir: inv_dir.into(),
            origin_4: [0, 1, 2].map(|a| Vec4::splat(origin[a])),
            inv_dir_4: [0, 1, 2].map(|a| Vec4::splat(inv_dir[a])),
            near_side: [0, 1, 2].map(|a| usize::from(inv_dir[a] < 0.0)),
            sheared,
        })
    }

    /// [`ShearedRay::hit`].
    #[inline(always)]
    fn hit(&self, packet: &Packet, range: (Vec4, Vec4)) -> (u32, Vec4, Vec4, Vec4) {
        self.sheared.hit(packet, range)
    }

    /// Entry distance into `bounds` if the ray meets it within `(t_min, t_max)`.
    fn enter(&self, bounds: &Aabb, t_min: f32, t_max: f32) -> Option<f32> {
        let lo = (bounds.min - self.origin) * self.inv_dir;
        let hi = (bounds.max - self.origin) * self.inv_dir;
        let enter = lo.min(hi).max_element().max(t_min);
        let exit = lo.max(hi).min_element().min(t_max);
        // Widened away from each other whatever their signs (`t_min` may be negative). An
        // infinite entry (or exit at minus infinity) turns into NaN here and the box is missed,
        // as it should be: widening first would let `max(t_min)` swallow the NaN.
        let enter_w = enter - enter.abs() * ROBUST_WIDEN;
        let exit_w = exit + exit.abs() * ROBUST_WIDEN;
        (enter_w <= exit_w).then_some(enter)
    }

    /// Slab test of the four boxes of `node` against the ray within `range` (`t_min`, `t_max`,
    /// splatted). Returns the mask of children hit and their entry distances.
    #[inline(always)]
    fn enter_node(&self, node: &Node, range: (Vec4, Vec4)) -> (u32, Vec4) {
        let mut enter = range.0;
        let mut exit = range.1;
        for a in 0..3 {
            let near = self.near_side[a];
            let t_near = (node.bounds[near][a] - self.origin_4[a]) * self.inv_dir_4[a];
            let t_far = (node.bounds[1 - near][a] - self.origin_4[a]) * self.inv_dir_4[a];
            enter = enter.max(t_near);
            exit = exit.min(t_far);
        }
        // As in `enter`: NaN from an infinite entry or exit compares false, a miss.
        let enter_w = enter - enter.abs() * ROBUST_WIDEN;
        let exit_w = exit + exit.abs() * ROBUST_WIDEN;
        (enter_w.cmple(exit_w).bitmask() & node.used, enter)
    }
}

impl ShearedRay {
    fn new(origin: Vec3, dir: Vec3) -> Option<Self> {
        if !dir.is_finite() || !origin.is_finite() || dir == Vec3::ZERO {
            return None;
        }
        let abs = dir.abs();
        let kz = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding, so that `u`, `v` and the sign of the determinant mean the same.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let axes = [kx, ky, kz];
        // d_kz is the largest component of a non-zero direction: its reciprocal is finite.
        let inv_kz = 1.0 / dir[kz];
        let shear = [dir[kx] * inv_kz, dir[ky] * inv_kz, inv_kz];
        Some(ShearedRay {
            axes,
            origin_k: axes.map(|a| Vec4::splat(origin[a])),
            shear: shear.map(Vec4::splat),
        })
    }

    /// Woop, Benthin & Wald 2013, double-sided, on the four triangles of `packet` at once:
    /// returns the mask of lanes hit with `t` in `range` (open), and `t`, `u`, `v` per lane.
    ///
    /// In coordinates where the ray runs from the origin along +z, the 2D edge functions
    /// `U = Cx·By − Cy·Bx` (and cyclic) are the barycentric weights times twice the area; the
    /// ray is inside when all three have one sign. A shared edge yields exactly negated values
    /// in its two triangles, which is what makes the test watertight.
    #[inline(always)]
    fn hit(&self, packet: &Packet, range: (Vec4, Vec4)) -> (u32, Vec4, Vec4, Vec4) {
        let [kx, ky, kz] = self.axes;
        let [sx, sy, sz] = self.shear;
        let [ox, oy, oz] = self.origin_k;
        let [a, b, c] = &packet.v;
        // Each vertex relative to the origin, sheared so that the ray runs along +z.
        let (az, bz, cz) = (a[kz] - oz, b[kz] - oz, c[kz] - oz);
        let (ax, bx, cx) = (
            a[kx] - ox - sx * az,
            b[kx] - ox - sx * bz,
            c[kx] - ox - sx * cz,
        );
        let (ay, by, cy) = (
            a[ky] - oy - sy * az,
            b[ky] - oy - sy * bz,
            c[ky] - oy - sy * cz,
        );
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        let zero = u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO);
        if zero.any() {
            // Only the triangles with a zero, as in the paper: a neighbour must see the same
            // values for a shared edge unless the ray passes exactly through it.
            let exact = edge_functions_f64([ax, bx, cx], [ay, by, cy]);
            u = Vec4::select(zero, exact[0], u);
            v = Vec4::select(zero, exact[1], v);
            w = Vec4::select(zero, exact[2], w);
        }
        let negative = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
        let positive = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
        // Inside: the three edge functions never have both signs.
        let inside = (negative & positive).bitmask() ^ 0xf;
        if inside == 0 {
            return (0, Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
        }
        let det = u + v + w;
        let t = (u * az + v * bz + w * cz) * sz / det;
        // A zero determinant makes `t` NaN or infinite, which fails the range test.
        let hit = inside & (t.cmpgt(range.0) & t.cmplt(range.1)).bitmask();
        (hit, t, v / det, w / det)
    }
}

/// The edge functions again in `f64`, where the products are exact, so a zero is a true zero
/// (the ray passes exactly through an edge or vertex) and the signs are right.
#[cold]
fn edge_functions_f64(x: [Vec4; 3], y: [Vec4; 3]) -> [Vec4; 3] {
    let x = x.map(|v| v.to_array().map(f64::from));
    let y = y.map(|v| v.to_array().map(f64::from));
    let edge = |p: usize, q: usize| {
        Vec4::from_array(std::array::from_fn(|lane| {
            (x[q][lane] * y[p][lane] - y[q][lane] * x[p][lane]) as f32
        }))
    };
    // Same products and order as in `Ray::hit`: U from (B, C), V from (C, A), W from (A, B).
    [edge(1, 2), edge(2, 0), edge(0, 1)]
}

/// A triangle as the builder sees it: its box, the box's centre and its input index. The
/// builder sorts these themselves, rather than indices into them, so that its passes over a
/// node's triangles read memory in order.
struct Prim {
    min: Vec3A,
    max: Vec3A,
    centre: Vec3A,
    id: u32,
}

impl Prim {
    fn new(id: u32, v: &[Vec3; 3]) -> Self {
        let min = Vec3A::from(v[0].min(v[1]).min(v[2]));
        let max = Vec3A::from(v[0].max(v[1]).max(v[2]));
        Prim {
            min,
            max,
            centre: (min + max) * 0.5,
            id,
        }
    }
}

/// An axis-aligned box being grown.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    min: Vec3A,
    max: Vec3A,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
    }

    fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Half the surface area (the SAH only compares areas).
    fn half_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3A::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// The binary tree as built, before it is collapsed into 4-wide nodes.
enum BuildNode {
    Leaf {
        bounds: Aabb,
        first: u32,
        count: u32,
    },
    Inner {
        bounds: Aabb,
        children: Box<[BuildNode; 2]>,
    },
}

impl BuildNode {
    fn bounds(&self) -> &Aabb {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Inner { bounds, .. } => bounds,
        }
    }
}

/// Number of packets needed for `n` triangles: the SAH's unit of intersection cost.
fn packets(n: u32) -> f32 {
    n.div_ceil(PACKET as u32) as f32
}

/// Builds the subtree over `prims` (a window starting at `first` of the full array),
/// reordering them so that every leaf is a contiguous run.
fn build_node(prims: &mut [Prim], first: u32, depth: usize) -> BuildNode {
    let mut bounds = Aabb::EMPTY;
    let mut centres = Aabb::EMPTY;
    for p in prims.iter() {
        bounds.grow(p.min, p.max);
        centres.grow(p.centre, p.centre);
    }
    let n = prims.len();
    let leaf = BuildNode::Leaf {
        bounds,
        first,
        count: n as u32,
    };
    // One packet is as cheap as it gets.
    if n <= PACKET {
        return leaf;
    }
    if depth >= MAX_SAH_DEPTH {
        return if n <= MAX_LEAF {
            leaf
        } else {
            split(prims, first, depth, n / 2, bounds)
        };
    }

    let extent = centres.max - centres.min;
    // Triangles counted, and their bounds grown, per bin and axis.
    let mut bins = [[(0u32, Aabb::EMPTY); BINS]; 3];
    let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), BINS as f32 / extent, Vec3A::ZERO);
    let bin_of = |c: Vec3A| -> [usize; 3] {
        // `as usize` saturates (and maps NaN to 0); `min` catches the top edge.
        let b = (c - centres.min) * scale;
        [
            (b.x as usize).min(BINS - 1),
            (b.y as usize).min(BINS - 1),
            (b.z as usize).min(BINS - 1),
        ]
    };
    for p in prims.iter() {
        for (axis, b) in bin_of(p.centre).into_iter().enumerate() {
            let bin = &mut bins[axis][b];
            bin.0 += 1;
            bin.1.grow(p.min, p.max);
        }
    }

    // Sweep each axis from the right, then from the left, costing every plane.
    let mut best: Option<(f32, usize, usize)> = None;
    for (axis, bins) in bins.iter().enumerate() {
        let spread = extent[axis] > 0.0; // false for NaN
        if !spread {
            continue;
        }
        let mut right_cost = [0.0f32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut count = 0;
        for b in (1..BINS).rev() {
            acc = acc.union(bins[b].1);
            count += bins[b].0;
            right_cost[b] = if count > 0 {
                acc.half_area() * packets(count)
            } else {
                f32::INFINITY
            };
        }
        let mut acc = Aabb::EMPTY;
        let mut count = 0;
        for b in 1..BINS {
            acc = acc.union(bins[b - 1].1);
            count += bins[b - 1].0;
            if count == 0 {
                continue;
            }
            let cost = acc.half_area() * packets(count) + right_cost[b];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }

    let mid = match best {
        Some((cost, axis, plane)) => {
            let split_cost = TRAVERSAL_COST + cost / bounds.half_area();
            // Also a leaf when the areas are degenerate (NaN).
            let split_pays = split_cost < packets(n as u32);
            if n <= MAX_LEAF && !split_pays {
                return leaf;
            }
            partition(prims, |p| bin_of(p.centre)[axis] < plane)
        }
        // All centres coincide: binning cannot separate them.
        None if n <= MAX_LEAF => return leaf,
        None => n / 2,
    };
    // Binning guarantees both sides are non-empty; halve anyway should that ever fail.
    let mid = if mid == 0 || mid == n { n / 2 } else { mid };
    split(prims, first, depth, mid, bounds)
}

/// Builds the two subtrees over `prims[..mid]` and `prims[mid..]` (in parallel when large),
/// and their parent.
fn split(prims: &mut [Prim], first: u32, depth: usize, mid: usize, bounds: Aabb) -> BuildNode {
    let n = prims.len();
    let (left_prims, right_prims) = prims.split_at_mut(mid);
    let right_first = first + mid as u32;
    let (left, right) = if n > PARALLEL_BUILD {
        rayon::join(
            || build_node(left_prims, first, depth + 1),
            || build_node(right_prims, right_first, depth + 1),
        )
    } else {
        (
            build_node(left_prims, first, depth + 1),
            build_node(right_prims, right_first, depth + 1),
        )
    };
    BuildNode::Inner {
        bounds,
        children: Box::new([left, right]),
    }
}

/// Moves the primitives for which `left` holds to the front; returns how many there are.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..prims.len() {
        if left(&prims[i]) {
            prims.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

/// Point-to-point visibility by shadow rays through a BVH over the scene's surfaces.
///
/// Every surface blocks light from both sides (a back face is opaque). Ray ends are lifted
/// off their surfaces by a small offset proportional to the scene size so that the surfaces
/// the ray starts and ends on are not hit.
pub struct Visibility {
    bvh: Bvh,
    offset: f64,
    /// The polygon each BVH triangle came from (an index into the polygons it was built from:
    /// [`Mesh::surface_polygons`] for [`Visibility::new`]).
    triangle_polygon: Vec<u32>,
}

impl Visibility {
    /// Builds the BVH over the mesh's surface polygons (fan-triangulated).
    pub fn new(mesh: &crate::mesh::Mesh) -> Self {
        let (mut lo, mut hi) = (
            glam::DVec3::splat(f64::INFINITY),
            glam::DVec3::splat(f64::NEG_INFINITY),
        );
        for p in &mesh.surface_polygons {
            let (a, b) = p.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let diameter = (hi - lo).length().max(1e-9);
        Self::from_polygons(mesh.surface_polygons.iter().map(|p| p.vertices()), diameter)
    }

    /// Builds the BVH over arbitrary opaque convex polygons (fan-triangulated; polygons of
    /// many vertices by [`crate::geometry::balanced_triangles`]), e.g. the
    /// occluders of a [`pair::PairProblem`]; ray ends are lifted by 1e-5 × `diameter`, the
    /// size of the whole configuration in metres.
    pub fn from_polygons<'p>(
        polygons: impl IntoIterator<Item = &'p [DVec3]>,
        diameter: f64,
    ) -> Self {
        let mut tris = Vec::new();
        let mut triangle_polygon = Vec::new();
        for (i, p) in polygons.into_iter().enumerate() {
            if p.len() >= crate::mesh::grid::GRID_MIN_VERTICES {
                // A polygon of many vertices by chords in halves, not by its fan: the fan's
                // n slivers from vertex 0 all overlap, and every query near them met all.
                for [a, b, c] in crate::geometry::balanced_triangles(p.len()) {
                    tris.push([p[a].as_vec3(), p[b].as_vec3(), p[c].as_vec3()]);
                    triangle_polygon.push(i as u32);
                }
                continue;
            }
            for w in p[1..].windows(2) {
                tris.push([p[0].as_vec3(), w[0].as_vec3(), w[1].as_vec3()]);
                triangle_polygon.push(i as u32);
            }
        }
        Self {
            bvh: Bvh::build(&tris),
            offset: 1e-5 * diameter.max(1e-9),
            triangle_polygon,
        }
    }

    /// Whether some surface triangle other than those `exclude` accepts (by polygon index and
    /// vertices) may lie in the capsule of `radius` (m) about the segment `a`–`b`: a
    /// conservative test that nothing can block light between two spheres (see
    /// [`Bvh::capsule_visit`]).
    pub fn maybe_blocked(
        &self,
        a: DVec3,
        b: DVec3,
        radius: f64,
        exclude: &dyn Fn(usize, &[Vec3; 3]) -> bool,
    ) -> bool {
        self.shaft_visit(
            a,
            b,
            radius,
            None,
            &Cull::default(),
            None,
            &mut |_, polygon, tri| !exclude(polygon, tri),
        )
    }

    /// Calls `visit(packet, polygon, vertices)` for every surface triangle that may lie in
    /// the capsule of `radius` (m) about the segment `a`–`b` (as [`Visibility::maybe_blocked`]),
    /// until it returns true; returns whether it did. `packet` is for
    /// [`Visibility::visible_among`]; `clip` as for [`Bvh::capsule_visit`]. With `among`, only
    /// the triangles of those packets (from an earlier visit whose capsule and box held this
    /// one's: the same triangles, without the traversal; [`Bvh::capsule_visit_among`]).
    #[allow(clippy::too_many_arguments)]
    pub fn shaft_visit(
        &self,
        a: DVec3,
        b: DVec3,
        radius: f64,
        clip: Option<[Vec3; 2]>,
        cull: &Cull,
        among: Option<&[u32]>,
        visit: &mut dyn FnMut(u32, usize, &[Vec3; 3]) -> bool,
    ) -> bool {
        let (a, b) = (a.as_vec3(), b.as_vec3());
        let radius = self.capsule_radius(radius);
        let visit = &mut |k, t: u32, tri: &[Vec3; 3]| {
            visit(k, self.triangle_polygon[t as usize] as usize, tri)
        };
        match among {
            Some(packets) => self
                .bvh
                .capsule_visit_among(packets, a, b, radius, clip, cull, visit),
            None => self.bvh.capsule_visit(a, b, radius, clip, cull, visit),
        }
    }

    /// [`Visibility::visible`] with only the triangles of `packets` as possible blockers
    /// (from [`Visibility::shaft_visit`]): the same answer when they hold every triangle that
    /// could cross the segment, without traversing the BVH.
    pub fn visible_among(&self, packets: &[u32], x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> bool {
        self.visible_among_trying(packets, x, nx, y, ny, &Blocker::default())
    }

    /// [`Visibility::visible_among`], trying the packet of `blocker` first
    /// ([`Bvh::segment_occluded_among_trying`]).
    pub fn visible_among_trying(
        &self,
        packets: &[u32],
        x: DVec3,
        nx: DVec3,
        y: DVec3,
        ny: DVec3,
        blocker: &Blocker,
    ) -> bool {
        let (a, b) = self.lifted(x, nx, y, ny);
        !self
            .bvh
            .segment_occluded_among_trying(packets, a, b, 1e-5, blocker)
    }

    /// The radius of the capsule that holds every segment between points within `radius`
    /// (m) of its axis' ends once they are lifted by the ray offset, with a margin for
    /// rounding.
    fn capsule_radius(&self, radius: f64) -> f32 {
        (radius * (1.0 + 1e-6) + self.offset) as f32
    }

    /// The ends of a visibility segment from `x` (normal `nx`) to `y` (normal `ny`), each
    /// lifted off its surface by the ray offset.
    fn lifted(&self, x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> (Vec3, Vec3) {
        (
            (x + nx * self.offset).as_vec3(),
            (y + ny * self.offset).as_vec3(),
        )
    }

    /// How far ray ends are lifted off their surfaces, m.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// The polygon (surface) a BVH triangle belongs to.
    pub fn polygon_of(&self, triangle: u32) -> usize {
        self.triangle_polygon[triangle as usize] as usize
    }

    /// True when nothing blocks the segment from `x` (on a surface with normal `nx`) to `y`
    /// (on a surface with normal `ny`).
    pub fn visible(&self, x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> bool {
        self.visible_trying(x, nx, y, ny, &Blocker::default())
    }

    /// [`Visibility::visible`], trying the packet of `blocker` before the traversal
    /// ([`Bvh::occluded_trying`]).
    pub fn visible_trying(
        &self,
        x: DVec3,
        nx: DVec3,
        y: DVec3,
        ny: DVec3,
        blocker: &Blocker,
    ) -> bool {
        let (a, b) = self.lifted(x, nx, y, ny);
        !self
            .bvh
            .occluded_trying(a, b - a, 1e-5, 1.0 - 1e-5, blocker)
    }

    /// The subtrees that hold every triangle within `radius` of the segment from `a` to `b`
    /// (and in the box `clip`), at most `most` of them: the capsule of
    /// [`Visibility::shaft_visit`], for [`Visibility::visible_in_trying`].
    pub fn shaft_subtrees(
        &self,
        a: DVec3,
        b: DVec3,
        radius: f64,
        clip: Option<[Vec3; 2]>,
        most: usize,
    ) -> Subtrees {
        let radius = self.capsule_radius(radius);
        self.bvh
            .capsule_subtrees(a.as_vec3(), b.as_vec3(), radius, clip, most)
    }

    /// [`Visibility::visible_trying`] for a segment inside the capsule that `subtrees` were
    /// listed for ([`Visibility::shaft_subtrees`]): the same answer, traversing those
    /// subtrees alone.
    pub fn visible_in_trying(
        &self,
        subtrees: &Subtrees,
        x: DVec3,
        nx: DVec3,
        y: DVec3,
        ny: DVec3,
        blocker: &Blocker,
    ) -> bool {
        let (a, b) = self.lifted(x, nx, y, ny);
        !self
            .bvh
            .occluded_in_trying(subtrees, a, b - a, 1e-5, 1.0 - 1e-5, blocker)
    }

    /// The underlying BVH.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Closest surface hit along a ray (for picking and tests).
    pub fn first_hit(&self, origin: Vec3, dir: Vec3) -> Option<Hit> {
        self.bvh.intersect(origin, dir, 0.0, f32::INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*: a small seeded generator, so the tests need no `rand`.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        /// Uniform in [0, 1).
        fn f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.f32()
        }
        fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
            Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
        }
    }

    /// `count` small triangles scattered in the unit cube.
    fn random_triangles(rng: &mut Rng, count: usize, size: f32) -> Vec<[Vec3; 3]> {
        (0..count)
            .map(|_| {
                let c = rng.vec3(0.0, 1.0);
                [
                    c + rng.vec3(-size, size),
                    c + rng.vec3(-size, size),
                    c + rng.vec3(-size, size),
                ]
            })
            .collect()
    }

    /// The packet test on a single triangle.
    fn hit_one(ray: &Ray, tri: &[Vec3; 3], t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let packet = Packet::new([tri; PACKET]);
        let (lanes, t, u, v) = ray.hit(&packet, (Vec4::splat(t_min), Vec4::splat(t_max)));
        assert!(lanes == 0 || lanes == 0xf, "lanes disagree: {lanes:b}");
        (lanes != 0).then(|| (t.x, u.x, v.x))
    }

    fn brute_intersect(
        triangles: &[[Vec3; 3]],
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let ray = Ray::new(origin, dir)?;
        let mut best = None;
        let mut t_max = t_max;
        for (i, tri) in triangles.iter().enumerate() {
            if let Some((t, u, v)) = hit_one(&ray, tri, t_min, t_max) {
                t_max = t;
                best = Some(Hit {
                    t,
                    triangle: i as u32,
                    u,
                    v,
                });
            }
        }
        best
    }

    /// Möller & Trumbore 1997 in f64, independent of the test under scrutiny.
    fn moller_trumbore(tri: &[Vec3; 3], origin: Vec3, dir: Vec3) -> Option<(f64, f64, f64)> {
        let [v0, v1, v2] = tri.map(|v| v.as_dvec3());
        let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
        let (e1, e2) = (v1 - v0, v2 - v0);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let s = o - v0;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            return None;
        }
        Some((e2.dot(q) / det, u, v))
    }

    #[test]
    fn matches_brute_force_on_random_scenes() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for (count, size) in [(1, 0.3), (3, 0.3), (50, 0.2), (2000, 0.05), (20_000, 0.02)] {
            let triangles = random_triangles(&mut rng, count, size);
            let bvh = Bvh::build(&triangles);
            assert_eq!(bvh.len(), count);
            let mut hits = 0;
            for _ in 0..3000 {
                let origin = rng.vec3(-0.5, 1.5);
                // Unnormalised on purpose: t must be in units of `dir`.
                let dir = rng.vec3(-1.0, 1.0) * rng.range(0.1, 3.0);
                let (t_min, t_max) = if rng.f32() < 0.5 {
                    (0.0, f32::INFINITY)
                } else {
                    (rng.range(0.0, 0.5), rng.range(0.5, 1.5))
                };
                let expected = brute_intersect(&triangles, origin, dir, t_min, t_max);
                let got = bvh.intersect(origin, dir, t_min, t_max);
                match (got, expected) {
                    (Some(g), Some(e)) => {
                        assert_eq!(g.t, e.t, "count {count}: origin {origin} dir {dir}");
                        assert!(
                            g.triangle == e.triangle
                                || triangles_tie(&triangles, g, e, origin, dir),
                            "count {count}: {g:?} vs {e:?}"
                        );
                        hits += 1;
                    }
                    (g, e) => assert_eq!(g, e, "count {count}: origin {origin} dir {dir}"),
                }
                assert_eq!(
                    bvh.occluded(origin, dir, t_min, t_max),
                    expected.is_some(),
                    "count {count}: origin {origin} dir {dir}"
                );
            }
            assert!(
                count < 50 || hits > 100,
                "too few hits ({hits}) to test much"
            );
        }
    }

    /// Two different triangles may be hit at exactly the same `t`; either answer is right.
    fn triangles_tie(triangles: &[[Vec3; 3]], a: Hit, b: Hit, origin: Vec3, dir: Vec3) -> bool {
        let ray = Ray::new(origin, dir).unwrap();
        let t_of = |h: Hit| {
            hit_one(&ray, &triangles[h.triangle as usize], 0.0, f32::INFINITY).map(|(t, _, _)| t)
        };
        t_of(a) == t_of(b)
    }

    #[test]
    fn triangle_test_agrees_with_moller_trumbore() {
        let mut rng = Rng(7);
        let mut hits = 0;
        for _ in 0..20_000 {
            let tri = random_triangles(&mut rng, 1, 0.5)[0];
            let origin = rng.vec3(-1.0, 2.0);
            // Aimed at the triangle's plane, in and around the triangle.
            let (b1, b2) = (rng.range(-0.2, 1.0), rng.range(-0.2, 1.0));
            let target = (1.0 - b1 - b2) * tri[0] + b1 * tri[1] + b2 * tri[2];
            let dir = (target - origin) * rng.range(0.2, 2.0);
            // Skip ill-conditioned cases (slivers, grazing rays), where f32 legitimately
            // differs from f64 by more than the tolerances below.
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            let longest = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]]
                .map(|e| e.length_squared())
                .into_iter()
                .fold(0.0, f32::max);
            if n.length() < 0.1 * longest || n.normalize().dot(dir.normalize()).abs() < 0.1 {
                continue;
            }
            let ray = Ray::new(origin, dir).unwrap();
            let got = hit_one(&ray, &tri, f32::NEG_INFINITY, f32::INFINITY);
            let expected = moller_trumbore(&tri, origin, dir);
            match (got, expected) {
                (Some((t, u, v)), Some((te, ue, ve))) => {
                    hits += 1;
                    let scale = 1.0 + te.abs();
                    assert!((t as f64 - te).abs() < 1e-4 * scale, "t {t} vs {te}");
                    assert!((u as f64 - ue).abs() < 1e-3, "u {u} vs {ue}");
                    assert!((v as f64 - ve).abs() < 1e-3, "v {v} vs {ve}");
                    let p = origin + t * dir;
                    let q = (1.0 - u - v) * tri[0] + u * tri[1] + v * tri[2];
                    assert!((p - q).length() < 1e-3 * scale as f32, "{p} vs {q}");
                }
                (None, None) => {}
                // Rays within rounding of an edge may legitimately differ; they are rare.
                (Some((_, u, v)), None) => assert!(u.min(v).min(1.0 - u - v) < 1e-4),
                (None, Some((_, u, v))) => assert!(u.min(v).min(1.0 - u - v) < 1e-4),
            }
        }
        assert!(hits > 1000, "only {hits} hits");
    }

    #[test]
    fn empty_bvh_hits_nothing() {
        let bvh = Bvh::build(&[]);
        assert!(bvh.is_empty());
        assert_eq!(bvh.len(), 0);
        assert!(!bvh.occluded(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY));
        assert_eq!(bvh.intersect(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY), None);
        assert!(!bvh.segment_occluded(Vec3::ZERO, Vec3::ONE, 1e-4));
    }

    /// The triangle x + y <= 1 in the plane z = `z`.
    fn unit_triangle(z: f32) -> [Vec3; 3] {
        [
            Vec3::new(0.0, 0.0, z),
            Vec3::new(1.0, 0.0, z),
            Vec3::new(0.0, 1.0, z),
        ]
    }

    #[test]
    fn both_sides_block_and_barycentrics_are_reported() {
        let bvh = Bvh::build(&[unit_triangle(1.0)]);
        let from_below = bvh.intersect(Vec3::new(0.25, 0.5, 0.0), Vec3::Z, 0.0, 10.0);
        let from_above = bvh.intersect(Vec3::new(0.25, 0.5, 3.0), -2.0 * Vec3::Z, 0.0, 10.0);
        let expected = Hit {
            t: 1.0,
            triangle: 0,
            u: 0.25,
            v: 0.5,
        };
        assert_eq!(from_below, Some(expected));
        assert_eq!(from_above, Some(expected));
    }

    #[test]
    fn ray_parallel_to_triangle_misses() {
        let bvh = Bvh::build(&[unit_triangle(0.0)]);
        // In the triangle's plane, through its interior, and just above it.
        for z in [0.0, 1e-6] {
            let origin = Vec3::new(-1.0, 0.25, z);
            assert!(!bvh.occluded(origin, Vec3::X, 0.0, f32::INFINITY), "z {z}");
            assert_eq!(bvh.intersect(origin, Vec3::X, 0.0, f32::INFINITY), None);
        }
    }

    #[test]
    fn t_range_is_open_and_respected() {
        let triangles = [unit_triangle(1.0), unit_triangle(2.0), unit_triangle(3.0)];
        let bvh = Bvh::build(&triangles);
        let o = Vec3::new(0.2, 0.2, 0.0);
        let t_of = |t_min, t_max| bvh.intersect(o, Vec3::Z, t_min, t_max).map(|h| h.t);
        assert_eq!(t_of(0.0, 10.0), Some(1.0));
        assert_eq!(t_of(1.0, 10.0), Some(2.0), "t_min is exclusive");
        assert_eq!(t_of(1.5, 10.0), Some(2.0));
        assert_eq!(t_of(0.0, 1.0), None, "t_max is exclusive");
        assert_eq!(t_of(1.5, 2.5), Some(2.0));
        assert_eq!(t_of(3.5, 10.0), None);
        assert_eq!(t_of(-10.0, 0.5), None);
        assert_eq!(t_of(2.0, 1.0), None, "empty interval");
        assert_eq!(t_of(f32::NAN, 10.0), None);
        let hit = bvh.intersect(o, Vec3::Z, 1.5, 10.0).unwrap();
        assert_eq!(hit.triangle, 1);
        // Behind the origin counts when t_min allows it.
        let back = bvh.intersect(Vec3::new(0.2, 0.2, 2.5), Vec3::Z, -10.0, 0.0);
        let back = back.unwrap();
        assert_eq!(back.triangle, 0);
        assert!((back.t + 1.5).abs() < 1e-6, "{back:?}");
        assert!(bvh.occluded(o, Vec3::Z, 1.5, 2.5));
        assert!(!bvh.occluded(o, Vec3::Z, 3.0, 10.0));
        assert!(!bvh.occluded(o, Vec3::Z, 0.0, 1.0));
    }

    #[test]
    fn degenerate_rays_hit_nothing() {
        let bvh = Bvh::build(&[unit_triangle(1.0)]);
        let o = Vec3::new(0.2, 0.2, 0.0);
        for dir in [Vec3::ZERO, Vec3::new(0.0, 0.0, f32::NAN), Vec3::INFINITY] {
            assert!(!bvh.occluded(o, dir, 0.0, 10.0));
            assert_eq!(bvh.intersect(o, dir, 0.0, 10.0), None);
        }
        assert!(!bvh.segment_occluded(o, o, 1e-4));
    }

    #[test]
    fn segment_blocked_only_by_something_between_its_ends() {
        // A wall at z = 1 between the end points, and the floors they stand on.
        let mut triangles = vec![unit_triangle(1.0)];
        triangles.push([
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(3.0, -1.0, 0.0),
            Vec3::new(-1.0, 3.0, 0.0),
        ]);
        triangles.push([
            Vec3::new(-1.0, -1.0, 2.0),
            Vec3::new(3.0, -1.0, 2.0),
            Vec3::new(-1.0, 3.0, 2.0),
        ]);
        let bvh = Bvh::build(&triangles);
        let a = Vec3::new(0.2, 0.2, 0.0);
        assert!(bvh.segment_occluded(a, Vec3::new(0.3, 0.3, 2.0), 1e-4));
        assert!(bvh.segment_occluded(Vec3::new(0.3, 0.3, 2.0), a, 1e-4));
        // Beside the wall: only the end points' own floors are touched.
        assert!(!bvh.segment_occluded(Vec3::new(0.9, 0.9, 0.0), Vec3::new(0.8, 0.8, 2.0), 1e-4));
        // Ending just short of the wall.
        assert!(!bvh.segment_occluded(a, Vec3::new(0.2, 0.2, 0.999), 1e-4));
    }

    #[test]
    fn shared_edges_and_vertices_are_watertight() {
        // A tilted quad cut into 2 × 2 cells of two triangles, so that it has interior edges
        // (diagonals and mid-lines) and a vertex shared by six triangles; no coordinate is
        // trivial. Rays are aimed at (the f32 rounding of) points on the interior edges and at
        // the central vertex, from both sides and many angles. The outer boundary is avoided:
        // a ray aimed at it may rightly miss by a rounding error. (Möller–Trumbore in f32, the
        // usual non-watertight test, lets about 6 % of these rays through.)
        let p = Vec3::new(0.1, 0.2, 0.3);
        let e1 = Vec3::new(0.9, 0.13, -0.21);
        let e2 = Vec3::new(-0.17, 0.77, 0.35);
        let vertex = |i: usize, j: usize| p + e1 * (i as f32 / 2.0) + e2 * (j as f32 / 2.0);
        let mut triangles = Vec::new();
        for i in 0..2 {
            for j in 0..2 {
                let (a, b, c, d) = (
                    vertex(i, j),
                    vertex(i + 1, j),
                    vertex(i + 1, j + 1),
                    vertex(i, j + 1),
                );
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        let bvh = Bvh::build(&triangles);
        let centre = vertex(1, 1);
        let interior_edges = [
            (vertex(0, 0), centre),
            (centre, vertex(2, 2)),
            (vertex(1, 0), vertex(1, 2)),
            (vertex(0, 1), vertex(2, 1)),
        ];
        let normal = e1.cross(e2).normalize();
        let mut targets = vec![centre];
        for (a, b) in interior_edges {
            targets.extend((1..200).map(|k| a + (b - a) * (k as f32 / 200.0)));
        }
        let mut misses = 0;
        let mut rays = 0;
        for target in targets {
            for j in 0..50 {
                let angle = j as f32 * 0.37;
                let tilt = Vec3::new(angle.cos(), angle.sin(), (angle * 1.7).sin()) * 0.6;
                let side = if j % 2 == 0 { 1.0 } else { -1.0 };
                let origin = target + (normal + tilt) * side;
                let dir = target - origin;
                rays += 2;
                if bvh.intersect(origin, dir, 0.0, 2.0).is_none() {
                    misses += 1;
                }
                if !bvh.occluded(origin, dir, 0.0, 2.0) {
                    misses += 1;
                }
            }
        }
        assert_eq!(misses, 0, "{misses} of {rays} rays slipped through");
    }

    #[test]
    fn degenerate_inputs_build() {
        // Identical triangles (all centres coincide), zero-area ones, and a line of them.
        let same = vec![unit_triangle(0.0); 1000];
        let bvh = Bvh::build(&same);
        let hit = bvh
            .intersect(Vec3::new(0.2, 0.2, -1.0), Vec3::Z, 0.0, 10.0)
            .unwrap();
        assert_eq!(hit.t, 1.0);
        let flat = vec![[Vec3::ONE, Vec3::ONE, Vec3::ONE]; 10];
        let bvh = Bvh::build(&flat);
        assert!(!bvh.occluded(Vec3::ZERO, Vec3::ONE, 0.0, 10.0));
        // Exponentially spaced: a badly unbalanced tree, which must respect the depth limit.
        let line: Vec<_> = (0..200)
            .map(|i| {
                let z = 1.1f32.powi(i) * 1e-6;
                unit_triangle(z)
            })
            .collect();
        let bvh = Bvh::build(&line);
        let hit = bvh
            .intersect(Vec3::new(0.2, 0.2, -1.0), Vec3::Z, 0.0, f32::MAX)
            .unwrap();
        assert_eq!(hit.triangle, 0);
        let hit = bvh
            .intersect(Vec3::new(0.2, 0.2, 1e3), -Vec3::Z, 0.0, f32::MAX)
            .unwrap();
        assert_eq!(hit.triangle, 199);
    }

    #[test]
    fn deep_tree_stack_agrees_with_shallow_one() {
        // Triangles spaced by powers of two make a chain-like tree; with random ones around
        // them, rays need the stack. Both stack sizes must give the brute-force answers.
        let mut rng = Rng(99);
        let mut triangles: Vec<_> = (0..240)
            .map(|i| unit_triangle(2f32.powi(i - 120)))
            .collect();
        triangles.extend(random_triangles(&mut rng, 500, 0.1));
        let bvh = Bvh::build(&triangles);
        for _ in 0..2000 {
            let origin = rng.vec3(-0.5, 1.5);
            let dir = rng.vec3(-1.0, 1.0);
            let ray = Ray::new(origin, dir).unwrap();
            let range = (Vec4::splat(0.0), Vec4::splat(f32::INFINITY));
            let expected = brute_intersect(&triangles, origin, dir, 0.0, f32::INFINITY);
            let shallow = bvh.intersect_from::<{ 3 * SHALLOW_DEPTH + 1 }>(&ray, range);
            let deep = bvh.intersect_from::<STACK>(&ray, range);
            assert_eq!(shallow.map(|h| h.t), expected.map(|h| h.t));
            assert_eq!(deep, shallow);
            let occluded = bvh
                .occluded_from::<STACK>(&ray, range, &[bvh.root])
                .is_some();
            assert_eq!(occluded, expected.is_some());
            assert_eq!(
                bvh.occluded_from::<{ 3 * SHALLOW_DEPTH + 1 + MOST_SUBTREES }>(
                    &ray,
                    range,
                    &[bvh.root]
                )
                .is_some(),
                occluded
            );
        }
    }

    #[test]
    fn is_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<Bvh>();
    }

    #[test]
    fn nodes_are_two_cache_lines() {
        assert_eq!(std::mem::size_of::<Node>(), 128);
        assert_eq!(std::mem::align_of::<Node>(), 64);
    }

    #[test]
    fn a_remembered_blocker_changes_no_answer() {
        // Runs of rays between two small patches across a cloud of triangles, as the rays of
        // one link are: each run shares one blocker, and every answer must be the brute
        // force's, through the whole BVH and through a list of packets alike.
        let mut rng = Rng(0xb10c);
        let triangles = random_triangles(&mut rng, 2000, 0.08);
        let bvh = Bvh::build(&triangles);
        let all: Vec<u32> = (0..bvh.packets.len() as u32).collect();
        let (mut blocked, mut remembered) = (0, 0);
        for _ in 0..100 {
            let (from, to) = (rng.vec3(-0.2, 1.2), rng.vec3(-0.2, 1.2));
            let (whole, listed) = (Blocker::default(), Blocker::default());
            for _ in 0..40 {
                let a = from + rng.vec3(-0.05, 0.05);
                let b = to + rng.vec3(-0.05, 0.05);
                let expected = brute_intersect(&triangles, a, b - a, 1e-4, 1.0 - 1e-4).is_some();
                let before = whole.0.get();
                let got = bvh.occluded_trying(a, b - a, 1e-4, 1.0 - 1e-4, &whole);
                assert_eq!(got, expected, "{a} to {b}");
                let among = bvh.segment_occluded_among_trying(&all, a, b, 1e-4, &listed);
                assert_eq!(among, expected, "{a} to {b}, listed");
                blocked += usize::from(expected);
                // Blocked and the blocker kept: the remembered packet answered.
                remembered +=
                    usize::from(expected && before != u32::MAX && whole.0.get() == before);
            }
        }
        // Enough blocked rays, and enough answered by the remembered packet, to mean something.
        assert!(
            blocked > 500 && remembered > 100,
            "{blocked} blocked, {remembered} remembered"
        );
    }

    /// A random capsule about the unit cube: long, short or of zero length, with or without
    /// a clipping box.
    fn random_capsule(rng: &mut Rng) -> Capsule {
        let a = rng.vec3(-0.5, 1.5);
        let b = match rng.next_u64() % 3 {
            0 => a,
            1 => a + rng.vec3(-0.05, 0.05),
            _ => rng.vec3(-0.5, 1.5),
        };
        let clip = (rng.next_u64() % 2 == 0).then(|| {
            let (p, q) = (rng.vec3(-0.2, 1.2), rng.vec3(-0.2, 1.2));
            [p.min(q), p.max(q)]
        });
        Capsule::new(a, b, rng.range(0.0, 0.4), clip)
    }

    #[test]
    fn rays_inside_a_capsule_meet_in_its_subtrees_what_they_meet_in_the_whole_tree() {
        let mut rng = Rng(0x0005_ab77_ee5e);
        let triangles = random_triangles(&mut rng, 3000, 0.05);
        let bvh = Bvh::build(&triangles);
        let (mut blocked, mut clear) = (0, 0);
        for round in 0..1000 {
            let capsule = random_capsule(&mut rng);
            let b = capsule.a + capsule.seg;
            let most = [1, 2, 4, MOST_SUBTREES][round % 4];
            let subtrees = bvh.capsule_subtrees(capsule.a, b, capsule.radius, capsule.clip, most);
            assert!(
                subtrees.0.len() <= most,
                "{} subtrees for {most}",
                subtrees.0.len()
            );
            // Segments between points of the capsule (and of its clipping box) stay inside
            // both: they are convex.
            // (None where a thousand tries found none: the box may miss the capsule.)
            let point = |rng: &mut Rng| {
                (0..1000).find_map(|_| {
                    let offset = rng.vec3(-1.0, 1.0);
                    let x = capsule.a + capsule.seg * rng.range(0.0, 1.0) + offset * capsule.radius;
                    let clipped = capsule
                        .clip
                        .is_some_and(|[lo, hi]| x.cmplt(lo).any() || x.cmpgt(hi).any());
                    (offset.length() <= 1.0 && !clipped).then_some(x)
                })
            };
            for _ in 0..20 {
                let (Some(x), Some(y)) = (point(&mut rng), point(&mut rng)) else {
                    break;
                };
                let whole = bvh.occluded(x, y - x, 1e-4, 1.0 - 1e-4);
                let within = bvh.occluded_in_trying(
                    &subtrees,
                    x,
                    y - x,
                    1e-4,
                    1.0 - 1e-4,
                    &Blocker::default(),
                );
                assert_eq!(whole, within, "segment {x} → {y}, subtrees {subtrees:?}");
                if whole {
                    blocked += 1;
                } else {
                    clear += 1;
                }
            }
        }
        // Both answers occur often enough for the comparison to mean something.
        assert!(
            blocked > 500 && clear > 500,
            "{blocked} blocked, {clear} clear"
        );
    }

    #[test]
    fn culling_four_triangles_at_once_agrees_with_one_at_a_time() {
        let mut rng = Rng(0xc0ff_ee00_1234);
        let triangles = random_triangles(&mut rng, 400, 0.2);
        let bvh = Bvh::build(&triangles);
        let (mut behind, mut lanes) = (0, 0);
        for round in 0..200 {
            let plane = |rng: &mut Rng| {
                let normal = rng.vec3(-1.0, 1.0).normalize_or(Vec3::Y);
                (rng.vec3(0.0, 1.0), normal)
            };
            let cull = Cull {
                planes: [
                    Some(plane(&mut rng)),
                    (round % 2 == 0).then(|| plane(&mut rng)),
                ],
                on_plane: f64::from(rng.range(0.0, 0.05)),
            };
            for k in 0..bvh.packets.len() {
                let mask = cull.behind(&bvh.packets[k]);
                for (lane, _, tri) in bvh.packet_triangles(k) {
                    let one = cull.planes.iter().flatten().any(|&(origin, normal)| {
                        tri.iter()
                            .all(|v| f64::from((*v - origin).dot(normal)) <= cull.on_plane)
                    });
                    assert_eq!(mask & (1 << lane) != 0, one, "packet {k} lane {lane}");
                    behind += usize::from(one);
                    lanes += 1;
                }
            }
        }
        // Both answers occur often.
        assert!(
            behind > lanes / 10 && behind < lanes * 9 / 10,
            "{behind} of {lanes}"
        );
    }

    #[test]
    fn four_boxes_at_once_agree_with_one_at_a_time() {
        let mut rng = Rng(0x5eed_cafe);
        let (mut held, mut boxes) = (0, 0);
        for _ in 0..20_000 {
            let capsule = random_capsule(&mut rng);
            let corners: [(Vec3, Vec3); 4] = std::array::from_fn(|_| {
                let p = rng.vec3(-0.2, 1.2);
                // Some boxes flat along an axis, as a floor triangle's is.
                let mut q = p + rng.vec3(0.0, 0.3);
                if rng.next_u64() % 4 == 0 {
                    q.y = p.y;
                }
                (p, q)
            });
            let lanes = |f: fn(&(Vec3, Vec3)) -> Vec3| {
                [0, 1, 2].map(|a| Vec4::from(corners.map(|c| f(&c)[a])))
            };
            let mask = capsule.holds4(lanes(|c| c.0), lanes(|c| c.1));
            for (lane, (min, max)) in corners.iter().enumerate() {
                let one = capsule.holds(*min, *max);
                assert_eq!(mask & (1 << lane) != 0, one, "lane {lane}: {min} {max}");
                held += usize::from(one);
                boxes += 1;
            }
        }
        // Both answers occur often enough for the comparison to mean something (about 3 % of
        // the boxes are held).
        assert!(held > 1000 && boxes - held > 1000, "{held} of {boxes}");
    }

    #[test]
    fn capsule_visit_reaches_every_triangle_the_capsule_may_hold() {
        let mut rng = Rng(0xfeed);
        let triangles = random_triangles(&mut rng, 3000, 0.05);
        let bvh = Bvh::build(&triangles);
        let mut must = 0;
        for _ in 0..300 {
            let capsule = random_capsule(&mut rng);
            let b = capsule.a + capsule.seg;
            let mut visited = vec![false; triangles.len()];
            bvh.capsule_visit(
                capsule.a,
                b,
                capsule.radius,
                capsule.clip,
                &Cull::default(),
                &mut |_, id, _| {
                    visited[id as usize] = true;
                    false
                },
            );
            for (id, t) in triangles.iter().enumerate() {
                // A triangle with a point in the capsule (and in the clipping box) is visited;
                // one visited may be held by its box (boxes are tested by their spheres, so a
                // triangle's may reach the capsule when its node's does not: both sound).
                let (min, max) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                let inside = |x: Vec3| {
                    let t = ((x - capsule.a).dot(capsule.seg)
                        / capsule.len2.max(f32::MIN_POSITIVE))
                    .clamp(0.0, 1.0);
                    let clipped = capsule
                        .clip
                        .is_some_and(|[lo, hi]| x.cmplt(lo).any() || x.cmpgt(hi).any());
                    !clipped && (capsule.a + capsule.seg * t).distance(x) < capsule.radius * 0.999
                };
                let centre = (t[0] + t[1] + t[2]) / 3.0;
                let samples = [
                    t[0],
                    t[1],
                    t[2],
                    centre,
                    (t[0] + t[1]) * 0.5,
                    (t[1] + t[2]) * 0.5,
                ];
                if samples.iter().any(|&x| inside(x)) {
                    assert!(visited[id], "triangle {id} in the capsule, not visited");
                    must += 1;
                }
                if visited[id] {
                    assert!(capsule.holds(min, max), "triangle {id} visited, not held");
                }
            }
        }
        assert!(must > 1000, "only {must} triangles in capsules");
    }
}

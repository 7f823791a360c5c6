//! Occlusion of many rays that share one origin (a receiver's hemisphere of directions), traced
//! together as a ray stream: a 4-wide BVH is walked once per bundle, each node carrying the
//! list of the bundle's rays that reach it, so deep nodes meet only the few rays that get
//! there. Each ray meets a node's four boxes, or a leaf's four triangles, in one SIMD test.
//! Where a list thins to a ray or two, those rays walk the rest of the subtree one by one.
//!
//! Triangles are tested as cones from the shared origin: a ray hits a triangle when its
//! direction lies inside the three planes through the origin and the triangle's edges. The
//! edge planes are shared exactly by neighbouring triangles, so a ray cannot slip across the
//! edge between two triangles of a closed mesh, and a triangle whose plane contains the origin
//! (a hit at `t = 0`) occludes nothing, as in Embree.

use glam::{Vec3A, Vec4};
use obvhs::bvh2::Bvh2;
use obvhs::triangle::Triangle;

#[cfg(target_arch = "x86_64")]
mod pairs;

/// Four child boxes side by side (one lane each), and what each child is.
#[derive(Clone, Copy, Debug)]
struct Node4 {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    /// An inner child's node index, or a leaf child's first triangle pack.
    child: [u32; 4],
    /// A leaf child's number of packs (0 for an inner child).
    packs: [u8; 4],
    /// Which lanes hold a child.
    used: u32,
}

impl Node4 {
    /// The lanes whose child is a leaf, as a mask.
    #[inline(always)]
    fn leaf_lanes(&self) -> u32 {
        (0..4).fold(0u32, |m, l| m | u32::from(self.packs[l] > 0) << l)
    }
}

/// Up to four triangles side by side; unused lanes are degenerate (they occlude nothing).
#[derive(Clone, Copy, Debug)]
struct TrianglePack {
    corners: [[Vec4; 3]; 3],
}

/// A 4-wide BVH laid out for bundles of rays from one origin.
#[derive(Default)]
pub(super) struct BundleTree {
    nodes: Vec<Node4>,
    packs: Vec<TrianglePack>,
}

impl BundleTree {
    /// From an obvhs binary BVH over `triangles` (its leaves index `primitive_indices`): each
    /// 4-wide node opens the binary children with the largest boxes until it has four.
    pub fn from_bvh2(bvh: &Bvh2, triangles: &[Triangle]) -> Self {
        let mut tree = BundleTree::default();
        if bvh.nodes.is_empty() {
            return tree;
        }
        // (binary node, 4-wide node to fill). A root leaf becomes the only child of a node.
        let mut todo = vec![(0usize, tree.new_node())];
        while let Some((binary, slot)) = todo.pop() {
            let root = &bvh.nodes[binary];
            let mut children = if root.is_leaf() {
                vec![binary]
            } else {
                vec![root.first_index as usize, root.first_index as usize + 1]
            };
            while children.len() < 4 {
                let widest = children
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| !bvh.nodes[**c].is_leaf())
                    .max_by(|a, b| bvh.nodes[*a.1].aabb.half_area().total_cmp(&bvh.nodes[*b.1].aabb.half_area()));
                let Some((k, &c)) = widest else { break };
                let first = bvh.nodes[c].first_index as usize;
                children[k] = first;
                children.push(first + 1);
            }
            for (lane, &c) in children.iter().enumerate() {
                let node = &bvh.nodes[c];
                // Grown by a few ulps, so float rounding in the slab test (a flat box, a ray
                // through its corner) never culls a ray that reaches a triangle inside.
                let pad = (node.aabb.max - node.aabb.min).max_element() * 1e-6
                    + node.aabb.min.abs().max(node.aabb.max.abs()).max_element() * 4.0 * f32::EPSILON;
                let (lo, hi) = (node.aabb.min - pad, node.aabb.max + pad);
                let target = &mut tree.nodes[slot];
                for axis in 0..3 {
                    target.lo[axis][lane] = lo[axis];
                    target.hi[axis][lane] = hi[axis];
                }
                target.used |= 1 << lane;
                if node.is_leaf() {
                    let range = node.first_index as usize..(node.first_index + node.prim_count) as usize;
                    let first = tree.packs.len() as u32;
                    for four in bvh.primitive_indices[range].chunks(4) {
                        tree.packs.push(TrianglePack::new(four.iter().map(|&i| &triangles[i as usize])));
                    }
                    let packs = (tree.packs.len() as u32 - first) as u8;
                    tree.nodes[slot].child[lane] = first;
                    tree.nodes[slot].packs[lane] = packs;
                } else {
                    let index = tree.new_node();
                    tree.nodes[slot].child[lane] = index as u32;
                    todo.push((c, index));
                }
            }
        }
        tree
    }

    fn new_node(&mut self) -> usize {
        let empty = Vec4::ZERO;
        self.nodes.push(Node4 { lo: [empty; 3], hi: [empty; 3], child: [0; 4], packs: [0; 4], used: 0 });
        self.nodes.len() - 1
    }

    pub fn byte_size(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node4>() + self.packs.len() * std::mem::size_of::<TrianglePack>()
    }

    /// Sets `blocked[i]` for each ray `i` of `rays` (indices into `directions`) that hits a
    /// triangle at a distance in `(0, tmax)`. Rays already marked blocked are skipped. Where the
    /// CPU has AVX2, two rays share each instruction ([`pairs`]); the flags are the same bits.
    pub fn occlude(&self, origin: Vec3A, directions: &[Vec3A], rays: &[u32], tmax: f32, blocked: &mut [bool]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.occlude_pairs(origin, directions, rays, tmax, blocked) };
        }
        self.occlude_portable(origin, directions, rays, tmax, blocked);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn occlude_pairs(&self, origin: Vec3A, directions: &[Vec3A], rays: &[u32], tmax: f32, blocked: &mut [bool]) {
        // SAFETY: this function runs only where the CPU has AVX2, all that `Pairs` needs.
        unsafe { self.walk::<pairs::Pairs>(origin, directions, rays, tmax, blocked) };
    }

    pub(super) fn occlude_portable(
        &self,
        origin: Vec3A,
        directions: &[Vec3A],
        rays: &[u32],
        tmax: f32,
        blocked: &mut [bool],
    ) {
        // SAFETY: `OneRay` needs only the target's baseline features.
        unsafe { self.walk::<OneRay>(origin, directions, rays, tmax, blocked) };
    }

    /// The walk itself, with the per-ray tests of kernel `K`.
    ///
    /// # Safety
    /// The CPU has the features `K` is compiled for (see [`Kernel`]).
    #[inline(always)]
    unsafe fn walk<K: Kernel>(
        &self,
        origin: Vec3A,
        directions: &[Vec3A],
        rays: &[u32],
        tmax: f32,
        blocked: &mut [bool],
    ) {
        if self.nodes.is_empty() || rays.is_empty() {
            return;
        }
        assert_eq!(blocked.len(), directions.len(), "one flag per direction");
        // The buffers are the thread's, kept between bundles.
        let mut scratch = SCRATCH.take();
        let WalkScratch { inverse, lists, stack, single_stack } = &mut scratch;
        // A zero component would make 0·∞ in the slab test: a tiny one gives the same slabs.
        // Only the listed rays' entries are written, and read.
        if inverse.len() < directions.len() {
            inverse.resize(directions.len(), Vec3A::ZERO);
        }
        for &i in rays {
            let d = directions[i as usize];
            inverse[i as usize] =
                Vec3A::select(d.abs().cmplt(Vec3A::splat(1e-30)), Vec3A::splat(1e30).copysign(d), d.recip());
        }
        // Each stacked node owns a range of `lists`; the one on top owns the highest range, so
        // popping it frees everything above its end.
        lists.clear();
        lists.extend_from_slice(rays);
        // Each stacked node also holds how many leaf tests had hit when its list was written:
        // while no test has hit since, no ray in it can have been blocked since. The root's
        // list may hold rays blocked before the walk.
        let mut hits = 0u32;
        stack.clear();
        stack.push((0, 0, rays.len() as u32, u32::MAX));
        let o = [Vec4::splat(origin.x), Vec4::splat(origin.y), Vec4::splat(origin.z)];
        while let Some((index, start, end, written)) = stack.pop() {
            let (start, end) = (start as usize, end as usize);
            // A node that few rays reach is walked ray by ray: below a few rays the list's
            // bookkeeping costs more than sharing the node's loads saves.
            if end - start <= SINGLE_RAY_LISTS {
                for &i in &lists[start..end] {
                    let i = i as usize;
                    if !blocked[i] {
                        let hit = self.occluded_one(index, &o, directions[i], inverse[i], tmax, single_stack);
                        blocked[i] = hit;
                        hits += u32::from(hit);
                    }
                }
                continue;
            }
            let node = &self.nodes[index as usize];
            let boxes = Boxes {
                lo: [node.lo[0] - o[0], node.lo[1] - o[1], node.lo[2] - o[2]],
                hi: [node.hi[0] - o[0], node.hi[1] - o[1], node.hi[2] - o[2]],
                used: node.used,
                tmax,
            };
            let centre = [boxes.lo[0] + boxes.hi[0], boxes.lo[1] + boxes.hi[1], boxes.lo[2] + boxes.hi[2]];
            let distance = (centre[0] * centre[0] + centre[1] * centre[1] + centre[2] * centre[2]).to_array();
            // Lanes from the farthest child to the nearest: the nearest is traced first, so its
            // list goes last (on top).
            let order = farthest_first(distance);
            // Child lists are written straight into `lists`: lane `l` at `slot[l]`, room for
            // every parent ray in each. `lists` only grows: what lies past `end` is stale, and
            // overwritten before it is read.
            let count = end - start;
            let mut slot = [0usize; 4];
            for (rank, &lane) in order.iter().enumerate() {
                slot[lane] = end + rank * count;
            }
            if lists.len() < end + 4 * count {
                lists.resize(end + 4 * count, 0);
            }
            let (parent, children) = lists.split_at_mut(end);
            // SAFETY: the caller's promise.
            let clean = written == hits;
            let length = unsafe {
                K::split(&boxes, inverse, &mut parent[start..end], clean, children, slot.map(|s| s - end), blocked)
            };
            let written = hits;
            // Leaves at once (cheap, and what they block leaves the other lists early), then
            // the inner children.
            // The leaves rays enter, as a mask (one branch per leaf, not two per lane).
            let entered = (0..4).fold(0u32, |m, l| m | u32::from(length[l] > 0) << l);
            let mut leaves = node.leaf_lanes() & entered;
            while leaves != 0 {
                let lane = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[lane] as usize;
                let listed = &lists[slot[lane]..slot[lane] + length[lane]];
                for pack in &self.packs[first..first + node.packs[lane] as usize] {
                    // SAFETY: the caller's promise.
                    hits += unsafe { K::occlude_pack(pack, origin, directions, listed, tmax, blocked) };
                }
            }
            // Without a branch per lane (whether a child is entered is data, and mispredicts):
            // every inner child is written, and the stack grows past those that rays enter.
            stack.reserve(4);
            let top = stack.len();
            let spare = stack.spare_capacity_mut();
            let mut pushed = 0;
            for lane in order {
                spare[pushed].write((node.child[lane], slot[lane] as u32, (slot[lane] + length[lane]) as u32, written));
                pushed += (node.packs[lane] == 0 && length[lane] > 0) as usize;
            }
            // SAFETY: the first `pushed` spare entries were just written.
            unsafe { stack.set_len(top + pushed) };
        }
        SCRATCH.set(scratch);
    }
}

/// A walk's buffers: the listed rays' reciprocal directions, the rays' lists, the stack of
/// nodes with their lists (node, list start, list end, leaf hits when written), and the
/// stack of a walk ray by ray.
#[derive(Default)]
struct WalkScratch {
    inverse: Vec<Vec3A>,
    lists: Vec<u32>,
    stack: Vec<(u32, u32, u32, u32)>,
    single_stack: Vec<u32>,
}

thread_local! {
    static SCRATCH: std::cell::Cell<WalkScratch> = Default::default();
}

/// Lists of at most this many rays are walked one ray at a time.
const SINGLE_RAY_LISTS: usize = 2;

impl BundleTree {
    /// Whether one ray (direction `d`, its reciprocal `inverse`) from the bundle's origin
    /// (`o`, splat) hits a triangle under node `root` within `(0, tmax)`: the same box and
    /// triangle tests as [`OneRay`], without lists.
    #[inline(always)]
    fn occluded_one(
        &self,
        root: u32,
        o: &[Vec4; 3],
        d: Vec3A,
        inverse: Vec3A,
        tmax: f32,
        stack: &mut Vec<u32>,
    ) -> bool {
        let origin = Vec3A::new(o[0].x, o[1].x, o[2].x);
        let far_limit = Vec4::splat(tmax);
        stack.clear();
        stack.push(root);
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            let (ax, bx) = ((node.lo[0] - o[0]) * inverse.x, (node.hi[0] - o[0]) * inverse.x);
            let (ay, by) = ((node.lo[1] - o[1]) * inverse.y, (node.hi[1] - o[1]) * inverse.y);
            let (az, bz) = ((node.lo[2] - o[2]) * inverse.z, (node.hi[2] - o[2]) * inverse.z);
            let near = ax.min(bx).max(ay.min(by)).max(az.min(bz)).max(Vec4::ZERO);
            let far = ax.max(bx).min(ay.max(by)).min(az.max(bz)).min(far_limit);
            let hits = near.cmple(far).bitmask() & node.used;
            if hits == 0 {
                continue;
            }
            let mut leaves = node.leaf_lanes() & hits;
            while leaves != 0 {
                let lane = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[lane] as usize;
                for pack in &self.packs[first..first + node.packs[lane] as usize] {
                    if pack.occludes(origin, d, far_limit) {
                        return true;
                    }
                }
            }
            // The inner children, the nearest entered last (on top).
            let inner = hits & !node.leaf_lanes();
            if inner.count_ones() <= 1 {
                if inner != 0 {
                    stack.push(node.child[inner.trailing_zeros() as usize]);
                }
                continue;
            }
            for lane in farthest_first(near.to_array()) {
                if inner >> lane & 1 != 0 {
                    stack.push(node.child[lane]);
                }
            }
        }
        false
    }
}

/// The lanes `0..4` ordered by decreasing `distance` (non-negative): a sorting network on
/// keys that hold a distance's bits with the lane in their lowest two (ties and the dropped
/// bits only reorder nearly equal children), without the branches an insertion sort
/// mispredicts.
#[inline(always)]
fn farthest_first(distance: [f32; 4]) -> [usize; 4] {
    debug_assert!(distance.iter().all(|d| *d >= 0.0), "{distance:?}: keys need non-negative distances");
    let mut key: [u32; 4] = std::array::from_fn(|lane| (distance[lane].to_bits() & !3) | lane as u32);
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (high, low) = (key[a].max(key[b]), key[a].min(key[b]));
        key[a] = high;
        key[b] = low;
    }
    key.map(|k| (k & 3) as usize)
}

/// A node's four child boxes relative to the bundle's origin.
struct Boxes {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    /// Which lanes hold a child.
    used: u32,
    tmax: f32,
}

/// The per-ray tests of the walk. An implementation may be compiled for CPU features beyond
/// the target's baseline (`Pairs`: AVX2), and may index without checks, hence `unsafe`: its
/// caller promises the CPU has those features, and that every listed ray indexes `inverse`,
/// `directions` and `blocked` (the walk checks each against `directions` before it begins).
trait Kernel {
    /// Appends each unblocked ray of `rays` to the list of every child box it enters within
    /// `[0, tmax]`: lane `l`'s list is written from `children[slot[l]]` on, over as many entries
    /// as `rays` has (scratch: what lies past a list's length is overwritten). `rays` itself is
    /// not read again and may be overwritten. When `clean`, no ray of `rays` is blocked, and the
    /// flags need not be read. Returns the lists' lengths.
    ///
    /// # Safety
    /// The CPU has the features the implementation is compiled for, and every index in `rays`
    /// is below `inverse.len()` and `blocked.len()`.
    unsafe fn split(
        boxes: &Boxes,
        inverse: &[Vec3A],
        rays: &mut [u32],
        clean: bool,
        children: &mut [u32],
        slot: [usize; 4],
        blocked: &[bool],
    ) -> [usize; 4];

    /// Marks each unblocked ray of `rays` that hits one of the pack's triangles within `(0, tmax)`,
    /// and returns how many listed rays hit (counting any already blocked).
    ///
    /// # Safety
    /// As for [`Kernel::split`], with `directions` for `inverse`.
    unsafe fn occlude_pack(
        pack: &TrianglePack,
        origin: Vec3A,
        directions: &[Vec3A],
        rays: &[u32],
        tmax: f32,
        blocked: &mut [bool],
    ) -> u32;
}

/// One ray against four boxes or four triangles per SIMD test.
struct OneRay;

impl Kernel for OneRay {
    #[inline(always)]
    unsafe fn split(
        boxes: &Boxes,
        inverse: &[Vec3A],
        rays: &mut [u32],
        clean: bool,
        children: &mut [u32],
        slot: [usize; 4],
        blocked: &[bool],
    ) -> [usize; 4] {
        let (lo, hi, far_limit) = (&boxes.lo, &boxes.hi, Vec4::splat(boxes.tmax));
        let mut length = [0usize; 4];
        for &i in rays.iter() {
            if !clean && blocked[i as usize] {
                continue;
            }
            let inv = inverse[i as usize];
            let (ax, bx) = (lo[0] * inv.x, hi[0] * inv.x);
            let (ay, by) = (lo[1] * inv.y, hi[1] * inv.y);
            let (az, bz) = (lo[2] * inv.z, hi[2] * inv.z);
            let near = ax.min(bx).max(ay.min(by)).max(az.min(bz)).max(Vec4::ZERO);
            let far = ax.max(bx).min(ay.max(by)).min(az.max(bz)).min(far_limit);
            let hits = near.cmple(far).bitmask() & boxes.used;
            for lane in 0..4 {
                children[slot[lane] + length[lane]] = i;
                length[lane] += ((hits >> lane) & 1) as usize;
            }
        }
        length
    }

    #[inline(always)]
    unsafe fn occlude_pack(
        pack: &TrianglePack,
        origin: Vec3A,
        directions: &[Vec3A],
        rays: &[u32],
        tmax: f32,
        blocked: &mut [bool],
    ) -> u32 {
        let Some(edges) = pack.edges(origin) else { return 0 };
        let far_limit = Vec4::splat(tmax);
        let mut hits = 0;
        for &i in rays {
            if !blocked[i as usize] && edges.hit(directions[i as usize], far_limit) {
                blocked[i as usize] = true;
                hits += 1;
            }
        }
        hits
    }
}

/// A pack's triangles seen from one origin: the planes through the origin and each edge,
/// oriented inwards, and the triangles' depth.
struct PackEdges {
    planes: [[Vec4; 3]; 3],
    /// a·(b×c): the plane's distance from the origin times twice the triangle's area.
    depth: Vec4,
    /// Lanes with a triangle whose plane misses the origin.
    live: u32,
}

impl PackEdges {
    /// Whether the ray along `d` hits one of the pack's triangles within `(0, far_limit)`.
    #[inline(always)]
    fn hit(&self, d: Vec3A, far_limit: Vec4) -> bool {
        let (x, y, z) = (Vec4::splat(d.x), Vec4::splat(d.y), Vec4::splat(d.z));
        let [ab, bc, ca] = &self.planes;
        let e0 = x * ab[0] + y * ab[1] + z * ab[2];
        let e1 = x * bc[0] + y * bc[1] + z * bc[2];
        let e2 = x * ca[0] + y * ca[1] + z * ca[2];
        // The hit is at t = depth / (e0 + e1 + e2) (the sum is d·normal, scaled alike).
        let inside = e0.cmpge(Vec4::ZERO) & e1.cmpge(Vec4::ZERO) & e2.cmpge(Vec4::ZERO);
        let near = self.depth.cmplt(far_limit * (e0 + e1 + e2));
        (inside & near).bitmask() & self.live != 0
    }
}

impl TrianglePack {
    /// Whether one ray from `origin` along `d` hits one of the pack's triangles within
    /// `(0, far_limit)`.
    #[inline(always)]
    fn occludes(&self, origin: Vec3A, d: Vec3A, far_limit: Vec4) -> bool {
        self.edges(origin).is_some_and(|edges| edges.hit(d, far_limit))
    }

    fn new<'a>(triangles: impl Iterator<Item = &'a Triangle>) -> Self {
        let mut corners = [[Vec4::ZERO; 3]; 3];
        for (lane, t) in triangles.enumerate() {
            for (corner, v) in [t.v0, t.v1, t.v2].into_iter().enumerate() {
                for axis in 0..3 {
                    corners[corner][axis][lane] = v[axis];
                }
            }
        }
        Self { corners }
    }

    /// The pack's edge planes from `origin`, or `None` when no lane can occlude.
    #[inline(always)]
    fn edges(&self, origin: Vec3A) -> Option<PackEdges> {
        let o = [Vec4::splat(origin.x), Vec4::splat(origin.y), Vec4::splat(origin.z)];
        let [a, b, c] = self.corners.map(|v| [v[0] - o[0], v[1] - o[1], v[2] - o[2]]);
        let cross = |p: [Vec4; 3], q: [Vec4; 3]| {
            [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
        };
        let (ab, bc, ca) = (cross(a, b), cross(b, c), cross(c, a));
        // a·(b×c) is zero when the origin lies in the plane (t = 0) or the lane is unused, and
        // its sign orients the edge planes inwards.
        let volume = a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2];
        let live = (volume.cmpne(Vec4::ZERO) & volume.abs().cmplt(Vec4::INFINITY)).bitmask();
        if live == 0 {
            return None;
        }
        let sign = Vec4::ONE.copysign(volume);
        let orient = |e: [Vec4; 3]| [e[0] * sign, e[1] * sign, e[2] * sign];
        Some(PackEdges { planes: [orient(ab), orient(bc), orient(ca)], depth: volume.abs(), live })
    }
}

#[cfg(test)]
mod tests {
    use super::farthest_first;

    /// The sorting network orders all 256 arrangements of four distances drawn from four values
    /// (every permutation, and every tie) farthest first, each lane once.
    #[test]
    fn children_are_ordered_farthest_first() {
        let values = [0.5f32, 3.0, 17.25, 1e6];
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    for d in 0..4 {
                        let lanes = [a, b, c, d];
                        let distance = lanes.map(|k| values[k]);
                        let order = farthest_first(distance);
                        let mut seen = order;
                        seen.sort();
                        assert_eq!(seen, [0, 1, 2, 3], "{distance:?} gave {order:?}");
                        let sorted: Vec<f32> = order.iter().map(|&l| distance[l]).collect();
                        assert!(sorted.windows(2).all(|w| w[0] >= w[1]), "{distance:?} gave {order:?}");
                    }
                }
            }
        }
    }
}

//! What the debugger shows of a wide tree, in terms a viewer can draw without the tree's
//! layout: the boxes of one level ([`WideBvh::boxes_at_level`]), and the nodes and leaves a
//! traversal entered ([`TraversalLog`], an observer of the renderer's own traversals) with
//! their boxes ([`WideBvh::visited_boxes`]).
//!
//! A node or leaf is named by a [`WideRef`]: a node by its index, a leaf by its parent and
//! slot (a leaf has no index of its own), so the level view and the visited list name the
//! same box the same way. A box is the one the traversal tests: the box its parent holds for
//! it (the root, which has no parent, gets the union of its children's).

use std::collections::HashMap;

use serde::Serialize;

use super::kernels::{Lanes, NodeWidth};
use super::{ChildRef, WideBvh};
use crate::bvh::{QueryKind, TraversalObserver};
use crate::geometry::Aabb;
use crate::ray::Ray;

/// A node or a leaf of a wide tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum WideRef {
    /// The node of this index in [`WideBvh::nodes`].
    Node(u32),
    /// The leaf in slot `slot` of node `parent`.
    Leaf {
        /// Index of the node that holds the leaf.
        parent: u32,
        /// Its slot in that node.
        slot: u32,
    },
}

/// A box of a wide tree: a node's or a leaf's, with its level (the root is level 0; a child
/// is one level below its parent).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideBox {
    /// Whose box it is.
    pub at: WideRef,
    /// Its level.
    pub level: u32,
    /// The box the traversal tests.
    pub bounds: Aabb,
}

impl WideBox {
    /// Whether it is a leaf's box.
    pub fn is_leaf(&self) -> bool {
        matches!(self.at, WideRef::Leaf { .. })
    }
}

/// One query a [`TraversalLog`] saw: its kind, its ray (with its real interval and time), and
/// the nodes and leaves it entered, in the order it entered them.
#[derive(Clone, Debug, PartialEq)]
pub struct LoggedQuery {
    /// What the query asked.
    pub kind: QueryKind,
    /// The ray, as the traversal got it (for [`QueryKind::ShadowGroup`], the shadow ray whose
    /// group the query was made for).
    pub ray: Ray,
    /// Nodes (node references) and leaves entered, in order.
    pub entered: Vec<ChildRef>,
}

/// Records every query of the wide tree it observes and what each entered: how the debugger
/// asks the renderer's own traversals what they visited ([`WideBvh::visited_boxes`] gives
/// the boxes).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraversalLog {
    /// The queries, in the order they ran.
    pub queries: Vec<LoggedQuery>,
}

impl TraversalObserver for TraversalLog {
    fn query(&mut self, kind: QueryKind, ray: &Ray) {
        self.queries.push(LoggedQuery { kind, ray: *ray, entered: Vec::new() });
    }

    fn entered(&mut self, index: u32) {
        if let Some(q) = self.queries.last_mut() {
            q.entered.push(ChildRef::node(index));
        }
    }

    fn entered_leaf(&mut self, leaf: ChildRef) {
        if let Some(q) = self.queries.last_mut() {
            q.entered.push(leaf);
        }
    }
}

/// Where a child sits: its parent, slot and level.
#[derive(Clone, Copy)]
struct Place {
    parent: u32,
    slot: u32,
    level: u32,
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// The box of node `index`: the union of its children's boxes (which is the box its
    /// parent holds for it, as the collapse stores the binary tree's boxes).
    pub fn node_box(&self, index: u32) -> Aabb {
        let node = &self.nodes[index as usize];
        (0..W).filter(|&i| node.child[i] != ChildRef::EMPTY).fold(Aabb::EMPTY, |b, i| b.union(node.child_bounds(i)))
    }

    /// The box the traversal tests for `at`: a node's ([`WideBvh::node_box`]), or the one its
    /// parent holds for a leaf; `None` when there is no such node, or no leaf in that slot.
    pub fn wide_box(&self, at: WideRef) -> Option<Aabb> {
        match at {
            WideRef::Node(i) => self.nodes.get(i as usize).map(|_| self.node_box(i)),
            WideRef::Leaf { parent, slot } => {
                let node = self.nodes.get(parent as usize)?;
                let child = *node.child.get(slot as usize)?;
                (child != ChildRef::EMPTY && child.is_leaf()).then(|| node.child_bounds(slot as usize))
            }
        }
    }

    /// Every box of the tree with its level, depth-first from the root (`f` sees each once).
    fn walk_boxes(&self, mut f: impl FnMut(WideBox)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![(0u32, 0u32, self.node_box(0))];
        while let Some((index, level, bounds)) = stack.pop() {
            f(WideBox { at: WideRef::Node(index), level, bounds });
            let node = &self.nodes[index as usize];
            for slot in (0..W).rev() {
                let child = node.child[slot];
                if child == ChildRef::EMPTY {
                    continue;
                }
                let b = node.child_bounds(slot);
                if child.is_leaf() {
                    f(WideBox { at: WideRef::Leaf { parent: index, slot: slot as u32 }, level: level + 1, bounds: b });
                } else {
                    stack.push((child.node_index(), level + 1, b));
                }
            }
        }
    }

    /// Levels of boxes: nodes and the leaves below the deepest ones (0 for an empty tree).
    pub fn box_levels(&self) -> u32 {
        let mut levels = 0;
        self.walk_boxes(|b| levels = levels.max(b.level + 1));
        levels
    }

    /// The boxes of the nodes at `level` and of the leaves at or above it (the course's view
    /// of the binary tree, [`crate::bvh::Bvh::boxes_at_level`], for the wide tree: every
    /// primitive is inside some box drawn).
    pub fn boxes_at_level(&self, level: u32) -> Vec<WideBox> {
        let mut out = Vec::new();
        self.walk_boxes(|b| {
            if b.level == level || (b.level < level && b.is_leaf()) {
                out.push(b);
            }
        });
        out
    }

    /// The boxes of what one query entered (`entered`: a [`LoggedQuery::entered`]), in the
    /// same order, each with its level.
    pub fn visited_boxes(&self, entered: &[ChildRef]) -> Vec<WideBox> {
        // Where each child of an entered node sits, filled in as the nodes are entered: a
        // traversal enters a node before its children.
        let mut places: HashMap<ChildRef, Place> = HashMap::new();
        let mut out = Vec::with_capacity(entered.len());
        for &c in entered {
            let Some(place) = places.get(&c).copied().or_else(|| self.locate(c)) else {
                // The root (or a reference not in this tree, which no traversal reports).
                if c == ChildRef::ROOT && !self.nodes.is_empty() {
                    self.enter_node(0, 0, &mut places);
                    out.push(WideBox { at: WideRef::Node(0), level: 0, bounds: self.node_box(0) });
                }
                continue;
            };
            let bounds = self.nodes[place.parent as usize].child_bounds(place.slot as usize);
            let at = if c.is_leaf() {
                WideRef::Leaf { parent: place.parent, slot: place.slot }
            } else {
                self.enter_node(c.node_index(), place.level, &mut places);
                WideRef::Node(c.node_index())
            };
            out.push(WideBox { at, level: place.level, bounds });
        }
        out
    }

    /// Note where the children of node `index` (at `level`) sit.
    fn enter_node(&self, index: u32, level: u32, places: &mut HashMap<ChildRef, Place>) {
        for (slot, &child) in self.nodes[index as usize].child.iter().enumerate() {
            if child != ChildRef::EMPTY {
                places.insert(child, Place { parent: index, slot: slot as u32, level: level + 1 });
            }
        }
    }

    /// Where reference `c` sits, found by a walk of the tree (for a reference whose parent a
    /// log does not hold); `None` for the root and for references not in the tree.
    fn locate(&self, c: ChildRef) -> Option<Place> {
        if c == ChildRef::ROOT {
            return None;
        }
        let mut found = None;
        self.walk_boxes(|b| {
            if let WideRef::Leaf { parent, slot } = b.at
                && found.is_none()
                && self.nodes[parent as usize].child[slot as usize] == c
            {
                found = Some(Place { parent, slot, level: b.level });
            }
        });
        if found.is_some() {
            return found;
        }
        // A node: its parent is the node holding it.
        let mut level_of = HashMap::new();
        self.walk_boxes(|b| {
            if let WideRef::Node(i) = b.at {
                level_of.insert(i, b.level);
            }
        });
        self.nodes.iter().enumerate().find_map(|(p, node)| {
            let slot = node.child.iter().position(|&x| x == c)?;
            Some(Place { parent: p as u32, slot: slot as u32, level: level_of.get(&(p as u32))? + 1 })
        })
    }
}

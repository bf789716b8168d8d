//! The back end both sensors share: what a match measures between two
//! nodes (`edge`), the graph of a stream's nodes and the frames hung
//! between them (`nodes`), the test of a true revisit ([`revisit`]) and
//! the one gated solve, loop closures checked against each other before
//! it (`solve`), and the place index revisits are looked up in
//! (`places`).
//!
//! A camera map's nodes are its sweeps: the moves between them its
//! chain, every two sweeps' match a loop closure. A laser log's nodes are
//! some of its scans: the registered steps between them its chain,
//! revisits of keyframes its loop closures.

pub(crate) mod edge;
pub(crate) mod nodes;
pub(crate) mod places;
pub mod revisit;
pub(crate) mod solve;

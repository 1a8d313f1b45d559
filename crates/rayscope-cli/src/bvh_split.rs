//! `rayscope bvh --split-candidates NODE`: the SAH's choice at a node of the binary BVH, as
//! JSON (`rayscope::bvh::SplitCandidates`).

use std::io::Write;

use anyhow::{Result, bail};
use clap::Args;
use rayscope::bvh::{BuildParams, split_candidates};

use crate::{SceneArgs, load};

/// `rayscope bvh`'s arguments.
#[derive(Args)]
pub struct BvhArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// The node (its index in the binary BVH's depth-first array; 0 is the root) whose
    /// candidate split planes to print.
    #[arg(long, value_name = "NODE")]
    split_candidates: u32,
}

/// Print the node's candidates.
pub fn cmd_bvh(args: BvhArgs) -> Result<()> {
    let (scene, _) = load(&args.scene)?;
    let g = &scene.geometry;
    let Some(c) = split_candidates(&g.bvh, &g.build_bounds(), args.split_candidates, &BuildParams::default()) else {
        bail!(
            "--split-candidates: node {} does not exist (the binary BVH has {} nodes)",
            args.split_candidates,
            g.bvh.nodes.len()
        );
    };
    let mut out = std::io::stdout().lock();
    serde_json::to_writer_pretty(&mut out, &c)?;
    writeln!(out)?;
    Ok(())
}

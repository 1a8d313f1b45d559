//! Reading course files: OBJ/MTL meshes ([`obj`]) and texture images ([`texture`]).

pub mod obj;
pub mod texture;

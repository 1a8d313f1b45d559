//! Reading course files: OBJ/MTL meshes ([`obj`]) and texture images ([`texture`]), each
//! through [`file`], which reads only regular files and no more than a set number of bytes.

pub mod file;
pub mod obj;
pub mod texture;

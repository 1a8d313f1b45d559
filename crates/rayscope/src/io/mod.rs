//! Reading course files: OBJ meshes ([`obj`], read in parallel by [`obj_parallel`] with the
//! exact number parsing of [`float`] where a file has the common forms only), their MTL
//! material libraries ([`mtl`]) and texture images ([`texture`], decoded by [`image_file`],
//! which `rayscope compare` reads images with too), each through [`file`], which reads only
//! regular files and no more than a set number of bytes, the text files line by line ([`lines`]). Before a mesh is
//! read, the memory it will need is reserved once ([`memory`]); exact duplicate faces are
//! dropped ([`duplicates`]). Both hash vertex indices with [`index_hash`]. PLY meshes ([`ply`])
//! and glTF 2.0 scenes ([`gltf`]) are read into the same groups; [`mesh_file`] tells the
//! formats apart.

pub mod duplicates;
pub mod file;
pub mod float;
pub mod gltf;
pub mod image_file;
pub mod index_hash;
pub mod lines;
pub mod memory;
pub mod mesh_file;
pub mod mtl;
pub mod obj;
pub mod obj_parallel;
pub mod ply;
pub mod texture;

//! Every file format in one place, on one bounds-checked byte reader (`bytes`) and one
//! atomic writer ([`fsutil`]): dense `.npy` level sets ([`npy`]), the sparse `.sls` format
//! ([`sls`]), OpenVDB ([`vdb`]), images (NIfTI, PNG, MetaImage, NRRD, `.npy`: [`image`]),
//! and the checks every loaded level set passes ([`input`]).

pub(crate) mod bytes;
pub mod fsutil;
pub mod image;
pub mod input;
pub mod mesh;
pub mod npy;
pub mod sls;
pub mod vdb;

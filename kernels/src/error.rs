//! The one error type of the crate. Kernels never fail; only the constructors of views and
//! the drivers that check lengths once per block return errors.

use core::fmt;

/// A length did not match what a block, stencil or field needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelError {
    /// A padded block's data has the wrong length for its dimensions and halo.
    BlockLength { expected: usize, got: usize },
    /// The output slice does not have one value per interior voxel.
    OutputLength { expected: usize, got: usize },
    /// A per-voxel input field (speed, velocity component, φⁿ) is shorter than the block.
    FieldLength { expected: usize, got: usize },
    /// A point stencil has the wrong number of values.
    StencilLength { expected: usize, got: usize },
    /// Block dimensions whose padded size overflows `usize`.
    BlockTooLarge,
    /// A benchmark block without voxels.
    EmptyBlock,
}

impl fmt::Display for KernelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            KernelError::BlockLength { expected, got } => {
                write!(f, "padded block has {got} values, expected {expected}")
            }
            KernelError::OutputLength { expected, got } => {
                write!(f, "output has {got} values, expected {expected}")
            }
            KernelError::FieldLength { expected, got } => {
                write!(f, "per-voxel field has {got} values, expected at least {expected}")
            }
            KernelError::StencilLength { expected, got } => {
                write!(f, "stencil has {got} values, expected {expected}")
            }
            KernelError::BlockTooLarge => write!(f, "block dimensions overflow usize"),
            KernelError::EmptyBlock => write!(f, "the block has no voxels"),
        }
    }
}

impl std::error::Error for KernelError {}

//! The level set a subcommand reads: a dense `.npy` field (positional) or an analytic shape
//! (`--shape ...`), with the grid's voxel size and half-width, loaded and checked by the
//! library's one loader ([`sparse_levelset::io::input`]).

use clap::{Args, ValueEnum};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect};
use sparse_levelset::io::sls;
use sparse_levelset::io::{self, AnyLevelSet, LevelSetFormat};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::hrle::HrleGrid;
use sparse_levelset::storage::shapes::Shape;
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ShapeKind {
    Sphere,
    Torus,
    Box,
    Ellipsoid,
    Spiral,
}

/// An analytic shape and its parameters (shared by `info`, `render` and `mesh`).
#[derive(Args)]
pub struct ShapeArgs {
    /// Analytic shape (default: sphere, when no field is given).
    #[arg(long, value_enum)]
    pub shape: Option<ShapeKind>,
    /// Sphere radius, or the spiral's outer radius [default: sphere 100, spiral 50].
    #[arg(long, allow_hyphen_values = true)]
    pub radius: Option<f64>,
    /// Torus radius of the centre circle.
    #[arg(long, default_value_t = 80.0, allow_hyphen_values = true)]
    pub major_radius: f64,
    /// Torus tube radius.
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    pub minor_radius: f64,
    /// Ellipsoid radii "a,b,c".
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [100.0, 70.0, 50.0])]
    pub radii: Vec<f64>,
    /// Box half extents "a,b,c".
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [60.0, 45.0, 30.0])]
    pub half_extents: Vec<f64>,
    /// Spiral extrusion depth (papers: 40 for radius 50).
    #[arg(long, default_value_t = 40.0, allow_hyphen_values = true)]
    pub depth: f64,
    /// Spiral turns (a multiple of 0.5).
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub turns: f64,
    /// Spiral arm thickness [default: radius / 5].
    #[arg(long, allow_hyphen_values = true)]
    pub thickness: Option<f64>,
    /// Shape centre "x,y,z" in world units (negative values are fine: --center -5,2,-3).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [0.0, 0.0, 0.0])]
    pub center: Vec<f64>,
}

impl ShapeArgs {
    /// The kind asked for (sphere by default).
    pub fn kind(&self) -> ShapeKind {
        self.shape.unwrap_or(ShapeKind::Sphere)
    }

    /// The shape's name in reports and errors.
    pub fn name(&self) -> String {
        format!("{:?}", self.kind()).to_lowercase()
    }

    /// The shape (its parameters are checked by [`input::check_shape`]); vectors must have
    /// three components.
    pub fn build(&self) -> Result<Shape, String> {
        let a = self;
        let v3 = |name: &str, v: &[f64]| -> Result<[f64; 3], String> {
            <[f64; 3]>::try_from(v)
                .map_err(|_| format!("--{name} takes three comma-separated numbers \"x,y,z\""))
        };
        let center = v3("center", &a.center)?;
        Ok(match a.kind() {
            ShapeKind::Sphere => Shape::Sphere { center, radius: a.radius.unwrap_or(100.0) },
            ShapeKind::Torus => {
                Shape::Torus { center, major_radius: a.major_radius, minor_radius: a.minor_radius }
            }
            ShapeKind::Box => {
                Shape::Box { center, half_extents: v3("half-extents", &a.half_extents)? }
            }
            ShapeKind::Ellipsoid => Shape::Ellipsoid { center, radii: v3("radii", &a.radii)? },
            ShapeKind::Spiral => {
                let radius = a.radius.unwrap_or(50.0);
                Shape::Spiral {
                    center,
                    radius,
                    depth: a.depth,
                    turns: a.turns,
                    thickness: a.thickness.unwrap_or(radius / 5.0),
                }
            }
        })
    }
}

/// The input level set of `info`, `render` and `mesh`: FIELD or a shape, on a grid.
#[derive(Args)]
pub struct SourceArgs {
    /// A dense float32 .npy level set (shape (nz, ny, nx), φ < 0 inside, world units), a
    /// sparse .sls file or an OpenVDB .vdb level set (both carry their own voxel size and
    /// half-width); without it, the shape given by --shape and its flags.
    #[arg(value_name = "FIELD.npy|FILE.sls|FILE.vdb", conflicts_with_all = [
        "shape", "radius", "major_radius", "minor_radius", "radii", "half_extents", "depth",
        "turns", "thickness", "center",
    ])]
    pub field: Option<PathBuf>,
    #[command(flatten)]
    pub shape: ShapeArgs,
    /// Voxel edge length in world units (also of FIELD).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub voxel_size: f32,
    /// Band half-width γ in voxels.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
}

/// A loaded and checked input.
pub enum Input {
    Field {
        name: String,
        field: DenseField,
    },
    Shape {
        name: String,
        shape: Shape,
    },
    /// A `.sls` file (with its header) or a `.vdb` file (without).
    Sparse {
        name: String,
        grid: Box<HrleGrid>,
        header: Option<sls::Header>,
    },
}

impl Input {
    /// The file's path or the shape's name.
    pub fn name(&self) -> &str {
        match self {
            Input::Field { name, .. } | Input::Shape { name, .. } | Input::Sparse { name, .. } => {
                name
            }
        }
    }
}

impl SourceArgs {
    /// The grid's spec (checked: what the computation can represent).
    pub fn spec(&self) -> Result<GridSpec, String> {
        GridSpec::new(self.voxel_size, [0.0; 3], self.half_width).map_err(|e| e.to_string())
    }

    /// Loads FIELD or builds the shape's description, and checks it against `expect`
    /// before any work.
    pub fn load(&self, expect: &Expect) -> Result<Input, String> {
        if let Some(path) = &self.field {
            let name = path.display().to_string();
            // A dense field stays dense (meshing and reports read it as a whole).
            if LevelSetFormat::from_path(path) == Some(LevelSetFormat::Npy) {
                let field = input::load_npy(path, expect).map_err(|e| e.to_string())?;
                return Ok(Input::Field { name, field });
            }
            let loaded = io::load_level_set(path, expect).map_err(|e| e.to_string())?;
            let grid = match loaded.level_set {
                AnyLevelSet::Hrle(grid) => grid,
                AnyLevelSet::Tiles(tiles) => {
                    HrleGrid::from_level_set(&tiles).map_err(|e| format!("{name}: {e}"))?
                }
            };
            return Ok(Input::Sparse { name, grid: Box::new(grid), header: loaded.sls_header });
        }
        let name = self.shape.name();
        let shape = self.shape.build()?;
        input::check_shape(&name, &shape, expect).map_err(|e| e.to_string())?;
        Ok(Input::Shape { name, shape })
    }
}

/// The grid of a dense `.npy` input (sparse files carry their own) and the worker threads:
/// the flags every command on level-set files shares.
#[derive(Args)]
pub struct FileGridArgs {
    /// Voxel edge length in world units of a .npy input.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub voxel_size: f32,
    /// Band half-width γ in voxels of a .npy input.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

/// A pool of `--threads` workers (all cores without the flag) and its size.
pub fn worker_pool(threads: Option<u32>) -> Result<(rayon::ThreadPool, usize), String> {
    let threads = threads.map_or_else(rayon::current_num_threads, |t| t as usize);
    let pool = levelset_cli::pin::pool(threads, false)
        .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    Ok((pool, threads))
}

/// Checks, before any work, that `output` can be written and names a level-set format; the
/// format.
pub fn level_set_output(output: &std::path::Path) -> Result<LevelSetFormat, String> {
    levelset_cli::output::check_output(output)?;
    LevelSetFormat::from_path(output).ok_or_else(|| {
        format!("{}: unknown output type; use {}", output.display(), LevelSetFormat::EXTENSIONS)
    })
}

impl FileGridArgs {
    /// The grid of a `.npy` input (checked).
    pub fn spec(&self) -> Result<GridSpec, String> {
        GridSpec::new(self.voxel_size, [0.0; 3], self.half_width).map_err(|e| e.to_string())
    }

    /// The worker pool and its size.
    pub fn pool(&self) -> Result<(rayon::ThreadPool, usize), String> {
        worker_pool(self.threads)
    }
}

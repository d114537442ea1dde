//! Writes the built-in coefficient tables (r = 1..=ECR_MAX_R, s = r..=r+2 on Gauss–Legendre
//! points; r − 1 moments on r + 1 Gauss–Lobatto points, `solve`'s checks) into OUT_DIR.

use ecr_codegen::render::rust_index;
use ecr_codegen::{Family, MAX_R, MethodTable, QuadratureKind};
use std::env;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;

/// Extra quadrature points beyond s = r that get built-in tables.
const EXTRA_S: usize = 2;

fn main() -> io::Result<()> {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=ECR_MAX_R");
    let max_r = match env::var("ECR_MAX_R") {
        Ok(v) => v
            .trim()
            .parse::<usize>()
            .ok()
            .filter(|r| (1..=MAX_R).contains(r))
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("ECR_MAX_R = {v:?}: expected an integer in 1..={MAX_R}"),
                )
            })?,
        Err(_) => 8,
    };
    let invalid =
        |e: ecr_codegen::CodegenError| io::Error::new(io::ErrorKind::InvalidInput, e.to_string());
    let mut tables = Vec::new();
    for r in 1..=max_r {
        for s in r..=r + EXTRA_S {
            tables.push(MethodTable::generate(Family::Ec, r, s).map_err(invalid)?);
        }
    }
    // The checks of `solve` (r − 1 moments on r + 1 Gauss–Lobatto points) for every answer
    // order r = 2..=max_r: generated here, not at a process's first solve (0.2–4 ms each).
    for r in 2..=max_r {
        let t = MethodTable::generate_with(Family::Ec, r - 1, r + 1, QuadratureKind::GaussLobatto)
            .map_err(invalid)?;
        tables.push(t);
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR")).join("tables.rs");
    let mut f = BufWriter::new(File::create(out)?);
    writeln!(
        f,
        "/// Largest r with built-in tables (env ECR_MAX_R at build time, default 8)."
    )?;
    writeln!(f, "pub const MAX_BUILTIN_R: usize = {max_r};")?;
    writeln!(f, "/// Built-in tables have s = r..=r + EXTRA_S.")?;
    writeln!(f, "pub const EXTRA_S: usize = {EXTRA_S};")?;
    f.write_all(rust_index(&tables, "ecr-runtime/build.rs").as_bytes())?;
    f.flush()
}

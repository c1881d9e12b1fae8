//! Exports a result store as a ParaView series: one `.vtu` (unstructured grid of vertex
//! cells, ASCII) per frame and a `.pvd` collection with the times.

use crate::{IoError, ResultStore};
use std::fmt::Write as _;
use std::path::Path;

fn file_err(path: &Path, source: std::io::Error) -> IoError {
    IoError::File {
        path: path.display().to_string(),
        source,
    }
}

/// Writes `DIR/<name>.pvd` and `DIR/<name>_<frame>.vtu` with every stored particle field
/// (of the stage `stage` of a staged run's store, default the last, named
/// `<name>-<stage>`). Returns the path of the `.pvd` file.
pub fn export_vtk(
    store_path: &Path,
    dir: &Path,
    stage: Option<&str>,
) -> Result<std::path::PathBuf, IoError> {
    let store = ResultStore::open_stage(store_path, stage)?;
    let dim = store.dimension();
    let name = store
        .attributes()
        .get("scene")
        .and_then(|s| s.get("name"))
        .and_then(|n| n.as_str())
        .unwrap_or("run")
        .to_string();
    let name = match store.stage_name() {
        Some(stage) => format!("{name}-{stage}"),
        None => name,
    };
    let times = store.times()?;
    let fields = store.fields()?;
    if !fields.iter().any(|f| f == "x") {
        return Err(IoError::Layout {
            path: store_path.display().to_string(),
            message: "the store has no particle positions (`x`); add it to output.fields".into(),
        });
    }
    std::fs::create_dir_all(dir).map_err(|e| file_err(dir, e))?;
    let mut pvd = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    for (frame, t) in times.iter().enumerate() {
        let (_, x) = store.frame("x", frame as u64)?;
        let n = x.len() / dim;
        let mut vtu = String::with_capacity(n * 64);
        let _ = write!(
            vtu,
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n"
        );
        for p in 0..n {
            for a in 0..3 {
                let v = if a < dim { x[p * dim + a] } else { 0.0 };
                let _ = write!(vtu, "{v} ");
            }
            vtu.push('\n');
        }
        vtu.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
        for p in 0..n {
            let _ = write!(vtu, "{p} ");
        }
        vtu.push_str(
            "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n",
        );
        for p in 0..n {
            let _ = write!(vtu, "{} ", p + 1);
        }
        vtu.push_str(
            "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n",
        );
        for _ in 0..n {
            vtu.push_str("1 ");
        }
        vtu.push_str("\n</DataArray>\n</Cells>\n<PointData>\n");
        for field in fields.iter().filter(|f| *f != "x") {
            let (shape, values) = store.frame(field, frame as u64)?;
            // `shape` is the frame's: the particles first, then each one's components.
            let comps: u64 = shape.iter().skip(1).product();
            let _ = writeln!(
                vtu,
                "<DataArray type=\"Float64\" Name=\"{field}\" NumberOfComponents=\"{comps}\" format=\"ascii\">"
            );
            for v in &values {
                let _ = write!(vtu, "{v} ");
            }
            vtu.push_str("\n</DataArray>\n");
        }
        vtu.push_str("</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
        let file = format!("{name}_{frame:05}.vtu");
        let path = dir.join(&file);
        std::fs::write(&path, vtu).map_err(|e| file_err(&path, e))?;
        let _ = writeln!(
            pvd,
            "<DataSet timestep=\"{t}\" part=\"0\" file=\"{file}\"/>"
        );
    }
    pvd.push_str("</Collection>\n</VTKFile>\n");
    let pvd_path = dir.join(format!("{name}.pvd"));
    std::fs::write(&pvd_path, pvd).map_err(|e| file_err(&pvd_path, e))?;
    Ok(pvd_path)
}

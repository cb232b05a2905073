//! Shape libraries (SHAPES.toml): `[[shape]]` tables of `name`, `obj` (a Wavefront OBJ file,
//! relative to the TOML file) and `material = { r_diff, r_spec, n_u, n_v }`, read the same way
//! by the sensor (the truth), the `photometry` service (the database) and `glint tool
//! photometry` (a user's own shapes).

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glint_physics::photometry::{parse_obj, Material, Shape};

/// Reads SHAPES.toml and every OBJ it names; every problem names the file and the field, or
/// the OBJ's line and column.
pub fn read_shapes(path: &Path) -> Result<Vec<(String, Shape)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let file = path.display();
    let table: toml::Table =
        toml::from_str(&text).map_err(|e| anyhow!("{file}: not valid TOML: {e}"))?;
    if let Some(k) = table.keys().find(|k| k.as_str() != "shape") {
        bail!("{file}: unknown field `{k}` (allowed: shape)");
    }
    let list = table
        .get("shape")
        .and_then(|v| v.as_array())
        .filter(|a| !a.is_empty())
        .ok_or_else(|| anyhow!("{file}: no [[shape]] tables"))?;
    if list.len() > 64 {
        bail!(
            "{file}: field `shape`: {} shapes; allowed 1..=64",
            list.len()
        );
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut shapes = vec![];
    for (i, s) in list.iter().enumerate() {
        let at = format!("shape[{i}]");
        let t = s
            .as_table()
            .ok_or_else(|| anyhow!("{file}: field `{at}` is not a table"))?;
        if let Some(k) = t
            .keys()
            .find(|k| !["name", "obj", "material"].contains(&k.as_str()))
        {
            bail!("{file}: unknown field `{at}.{k}` (allowed: name, obj, material)");
        }
        let text_field = |k: &str| -> Result<String> {
            t.get(k)
                .and_then(|v| v.as_str())
                .map(str::to_string)
                .ok_or_else(|| anyhow!("{file}: field `{at}.{k}` is missing or not a string"))
        };
        let name = text_field("name")?;
        if shapes.iter().any(|(n, _)| *n == name) {
            bail!("{file}: field `{at}.name`: `{name}` is named twice");
        }
        let m = t
            .get("material")
            .and_then(|v| v.as_table())
            .ok_or_else(|| anyhow!("{file}: field `{at}.material` is missing or not a table"))?;
        let num = |k: &str, lo: f64, hi: f64| -> Result<f64> {
            let v = match m.get(k) {
                Some(toml::Value::Float(f)) => *f,
                Some(toml::Value::Integer(i)) => *i as f64,
                _ => bail!("{file}: field `{at}.material.{k}` is missing or not a number"),
            };
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                bail!(
                    "{file}: field `{at}.material.{k}`: {v} is out of range; allowed {lo}..={hi}"
                );
            }
            Ok(v)
        };
        let material = Material {
            r_diff: num("r_diff", 0.0, 1.0)?,
            r_spec: num("r_spec", 0.0, 1.0)?,
            n_u: num("n_u", 0.0, 1e6)?,
            n_v: num("n_v", 0.0, 1e6)?,
        };
        let obj = dir.join(text_field("obj")?);
        let obj_text = std::fs::read_to_string(&obj)
            .with_context(|| format!("{file}: field `{at}.obj`: cannot read {}", obj.display()))?;
        let shape =
            parse_obj(&obj_text, material).map_err(|e| anyhow!("{}: {e}", obj.display()))?;
        shapes.push((name, shape));
    }
    Ok(shapes)
}

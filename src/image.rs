//! PNG output: the rendered image and the heat map of node tests per pixel.

use std::path::Path;

/// Writes an 8-bit RGB PNG, atomically (temporary file, then rename).
pub fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), String> {
    write_png_with(path, width, height, rgb, false)
}

/// [`write_png`] with the encoder's best compression and adaptive filters:
/// for plots, whose flat colours and thin lines compress well.
pub fn write_png_small(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), String> {
    write_png_with(path, width, height, rgb, true)
}

fn write_png_with(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
    small: bool,
) -> Result<(), String> {
    let mut tmp = golden::output::AtomicFile::create(path)?;
    {
        let mut enc = png::Encoder::new(std::io::BufWriter::new(tmp.file()), width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        if small {
            enc.set_compression(png::Compression::Best);
            enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        }
        let mut w = enc
            .write_header()
            .map_err(|e| format!("{}: {e}", path.display()))?;
        w.write_image_data(rgb)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    tmp.commit()
}

/// Maps counts to a black-blue-red-yellow-white ramp, scaled to the largest count.
pub fn heat_rgb(counts: &[u64]) -> Vec<u8> {
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    let stops = [
        [0.0, 0.0, 0.0],
        [0.1, 0.1, 0.8],
        [0.9, 0.1, 0.1],
        [1.0, 0.9, 0.1],
        [1.0, 1.0, 1.0],
    ];
    let mut out = Vec::with_capacity(counts.len() * 3);
    for &c in counts {
        let x = (c as f32 / max) * (stops.len() - 1) as f32;
        let i = (x.floor() as usize).min(stops.len() - 2);
        let f = x - i as f32;
        for (a, b) in stops[i].iter().zip(&stops[i + 1]) {
            let v = a * (1.0 - f) + b * f;
            out.push((v * 255.0).round() as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_ramp_ends() {
        let h = heat_rgb(&[0, 10]);
        assert_eq!(&h[..3], &[0, 0, 0]);
        assert_eq!(&h[3..], &[255, 255, 255]);
    }
}

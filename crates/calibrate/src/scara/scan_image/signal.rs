//! The scan as ink: one byte per pixel, larger where there is more ink whatever the colours (dark or coloured
//! filament on a light bed or paper, light filament on a dark one), and the background it stands out from (a
//! coarse grid of local medians, so an uneven lighting or a yellowed sheet does not read as ink).

use super::ScanImageError;

/// Largest image taken (pixels): a 300 × 300 mm pattern at 1200 dpi is 2.0e8.
pub const MAX_PIXELS: u64 = 250_000_000;

/// A decoded scan: its ink, one byte per pixel, row by row.
#[derive(Debug, Clone)]
pub struct ScanImage {
    pub width: usize,
    pub height: usize,
    ink: Vec<u8>,
}

impl ScanImage {
    /// From 8-bit RGB triples (`width × height × 3` bytes).
    pub fn from_rgb8(width: usize, height: usize, rgb: &[u8]) -> Result<Self, ScanImageError> {
        check_size(width, height, rgb.len(), 3)?;
        let light = light_background(rgb.chunks_exact(3).map(|p| p[0].max(p[1]).max(p[2])));
        let ink = rgb
            .chunks_exact(3)
            .map(|p| {
                if light {
                    255 - p[0].min(p[1]).min(p[2])
                } else {
                    p[0].max(p[1]).max(p[2])
                }
            })
            .collect();
        Ok(Self { width, height, ink })
    }

    /// From 8-bit grey levels (`width × height` bytes).
    pub fn from_luma8(width: usize, height: usize, luma: Vec<u8>) -> Result<Self, ScanImageError> {
        check_size(width, height, luma.len(), 1)?;
        let light = light_background(luma.iter().copied());
        let ink = if light {
            luma.into_iter().map(|v| 255 - v).collect()
        } else {
            luma
        };
        Ok(Self { width, height, ink })
    }

    /// Decodes a PNG or JPEG file's bytes (`name` for messages).
    pub fn decode(bytes: &[u8], name: &str) -> Result<Self, ScanImageError> {
        let bad = |e: image::ImageError| ScanImageError::Decode {
            file: name.to_string(),
            message: e.to_string(),
        };
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ScanImageError::Decode {
                file: name.to_string(),
                message: e.to_string(),
            })?;
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(MAX_PIXELS * 4);
        reader.limits(limits);
        let (w, h) = reader.into_dimensions().map_err(bad)?;
        if u64::from(w) * u64::from(h) > MAX_PIXELS {
            return Err(ScanImageError::TooLarge {
                file: name.to_string(),
                width: w as usize,
                height: h as usize,
            });
        }
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ScanImageError::Decode {
                file: name.to_string(),
                message: e.to_string(),
            })?;
        reader.limits(limits_for(w, h));
        let decoded = reader.decode().map_err(bad)?;
        let (w, h) = (decoded.width() as usize, decoded.height() as usize);
        if decoded.color().has_color() {
            Self::from_rgb8(w, h, decoded.to_rgb8().as_raw())
        } else {
            Self::from_luma8(w, h, decoded.to_luma8().into_raw())
        }
    }

    /// Reads and decodes a scan file.
    pub fn open(path: &std::path::Path) -> Result<Self, ScanImageError> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| ScanImageError::Read {
            file: name.clone(),
            message: e.to_string(),
        })?;
        Self::decode(&bytes, &name)
    }

    /// The ink at pixel (x, y), 0 outside the image.
    pub fn ink_at(&self, x: usize, y: usize) -> u8 {
        if x < self.width && y < self.height {
            self.ink[y * self.width + x]
        } else {
            0
        }
    }

    pub fn ink(&self) -> &[u8] {
        &self.ink
    }
}

/// Room for the decoder: the image in its own format (up to 4 channels of 16 bits) and its conversion.
fn limits_for(w: u32, h: u32) -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_alloc = Some((u64::from(w) * u64::from(h) * 12).max(1 << 26));
    limits
}

fn check_size(
    width: usize,
    height: usize,
    len: usize,
    channels: usize,
) -> Result<(), ScanImageError> {
    if width == 0
        || height == 0
        || width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(channels))
            != Some(len)
    {
        return Err(ScanImageError::Decode {
            file: String::new(),
            message: format!("{width} × {height} pixels do not match {len} bytes"),
        });
    }
    Ok(())
}

/// Whether most of the image is light (more than half of a sample of pixels at 128 or above).
fn light_background(values: impl Iterator<Item = u8>) -> bool {
    let (mut light, mut all) = (0usize, 0usize);
    for v in values.step_by(7) {
        light += usize::from(v >= 128);
        all += 1;
    }
    2 * light >= all
}

/// The background's ink level: medians of square cells, each smoothed with its neighbours (a cell that a cross
/// fills more than half is outvoted), read bilinearly between cell centres.
#[derive(Debug, Clone)]
pub struct Background {
    cell: usize,
    nx: usize,
    ny: usize,
    values: Vec<f32>,
}

impl Background {
    pub fn of(image: &ScanImage, cell: usize) -> Self {
        let cell = cell.max(4);
        let (nx, ny) = (image.width.div_ceil(cell), image.height.div_ceil(cell));
        let step = (cell / 16).max(1);
        let mut raw = vec![0f32; nx * ny];
        let mut sample = Vec::with_capacity((cell / step + 1).pow(2));
        for cy in 0..ny {
            for cx in 0..nx {
                sample.clear();
                for y in (cy * cell..((cy + 1) * cell).min(image.height)).step_by(step) {
                    for x in (cx * cell..((cx + 1) * cell).min(image.width)).step_by(step) {
                        sample.push(image.ink[y * image.width + x]);
                    }
                }
                raw[cy * nx + cx] = median_u8(&mut sample);
            }
        }
        let mut values = vec![0f32; nx * ny];
        let mut near = Vec::with_capacity(9);
        for cy in 0..ny {
            for cx in 0..nx {
                near.clear();
                for y in cy.saturating_sub(1)..(cy + 2).min(ny) {
                    for x in cx.saturating_sub(1)..(cx + 2).min(nx) {
                        near.push(raw[y * nx + x]);
                    }
                }
                near.sort_by(f32::total_cmp);
                values[cy * nx + cx] = near[near.len() / 2];
            }
        }
        Self {
            cell,
            nx,
            ny,
            values,
        }
    }

    /// The background at image point (x, y) (pixel centres at integer + 0.5).
    pub fn at(&self, x: f64, y: f64) -> f64 {
        let fx = (x / self.cell as f64 - 0.5).clamp(0.0, (self.nx - 1) as f64);
        let fy = (y / self.cell as f64 - 0.5).clamp(0.0, (self.ny - 1) as f64);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.nx - 1), (y0 + 1).min(self.ny - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let v = |x: usize, y: usize| f64::from(self.values[y * self.nx + x]);
        let top = v(x0, y0) * (1.0 - tx) + v(x1, y0) * tx;
        let bottom = v(x0, y1) * (1.0 - tx) + v(x1, y1) * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

fn median_u8(v: &mut [u8]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable(mid);
    f32::from(*m)
}

/// The ink above the background at a point, bilinear between pixel centres (pixel (i, j) has its centre at
/// (i + 0.5, j + 0.5)).
pub fn signal_at(image: &ScanImage, bg: &Background, x: f64, y: f64) -> f64 {
    let (fx, fy) = (x - 0.5, y - 0.5);
    if !(fx >= 0.0 && fy >= 0.0) {
        return 0.0;
    }
    let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
    if x0 + 1 >= image.width || y0 + 1 >= image.height {
        return 0.0;
    }
    let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
    let v = |x: usize, y: usize| f64::from(image.ink[y * image.width + x]);
    let top = v(x0, y0) * (1.0 - tx) + v(x0 + 1, y0) * tx;
    let bottom = v(x0, y0 + 1) * (1.0 - tx) + v(x0 + 1, y0 + 1) * tx;
    top * (1.0 - ty) + bottom * ty - bg.at(x, y)
}

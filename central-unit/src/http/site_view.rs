//! The floor plan as the page draws it (`/api/site`): walls, columns, cells,
//! transmitters and the extent of it all. The site model itself has no JSON
//! form (its file is TOML); this is the part a map needs.

use ickon_proto::site::Site;
use serde::Serialize;

/// One cell's floor polygon.
#[derive(Debug, Clone, Serialize)]
pub struct CellShape {
    /// Cell id.
    pub id: String,
    /// Polygon, metres.
    pub polygon: Vec<[f64; 2]>,
}

/// One transmitter.
#[derive(Debug, Clone, Serialize)]
pub struct TxMark {
    /// Transmitter id.
    pub id: u32,
    /// Its cell.
    pub cell: String,
    /// Position on the ceiling, metres.
    pub x_m: f64,
    /// Position on the ceiling, metres.
    pub y_m: f64,
}

/// The floor plan.
#[derive(Debug, Clone, Serialize)]
pub struct SiteView {
    /// Site name.
    pub name: String,
    /// Lower-left and upper-right corners of everything drawn, metres.
    pub bounds_m: [f64; 4],
    /// Cells.
    pub cells: Vec<CellShape>,
    /// Transmitters.
    pub transmitters: Vec<TxMark>,
    /// Walls as segments `[x0, y0, x1, y1]`, metres.
    pub walls: Vec<[f64; 4]>,
    /// Columns' polygons, metres.
    pub columns: Vec<Vec<[f64; 2]>>,
    /// Robots of the site.
    pub robots: Vec<String>,
}

impl From<&Site> for SiteView {
    fn from(site: &Site) -> Self {
        let walls: Vec<[f64; 4]> = site
            .walls
            .iter()
            .map(|w| [w.from[0], w.from[1], w.to[0], w.to[1]])
            .collect();
        let points = site
            .cells
            .iter()
            .flat_map(|c| c.polygon.iter().copied())
            .chain(site.columns.iter().flat_map(|c| c.polygon.iter().copied()))
            .chain(walls.iter().flat_map(|w| [[w[0], w[1]], [w[2], w[3]]]))
            .chain(
                site.transmitters
                    .iter()
                    .map(|t| [t.position_m[0], t.position_m[1]]),
            );
        let mut bounds_m = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for [x, y] in points {
            bounds_m = [
                bounds_m[0].min(x),
                bounds_m[1].min(y),
                bounds_m[2].max(x),
                bounds_m[3].max(y),
            ];
        }
        if !bounds_m.iter().all(|v| v.is_finite()) {
            bounds_m = [0.0, 0.0, 1.0, 1.0];
        }
        Self {
            name: site.name.clone(),
            bounds_m,
            cells: site
                .cells
                .iter()
                .map(|c| CellShape {
                    id: c.id.clone(),
                    polygon: c.polygon.clone(),
                })
                .collect(),
            transmitters: site
                .transmitters
                .iter()
                .map(|t| TxMark {
                    id: t.id,
                    cell: t.cell.clone(),
                    x_m: t.position_m[0],
                    y_m: t.position_m[1],
                })
                .collect(),
            walls,
            columns: site.columns.iter().map(|c| c.polygon.clone()).collect(),
            robots: site.robots.iter().map(|r| r.id.clone()).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_site_is_drawn_whole_within_its_bounds() {
        let (site, _, _) = Site::load_or_default(None).expect("built-in site");
        let v = SiteView::from(&site);
        assert_eq!(v.cells.len(), site.cells.len());
        assert_eq!(v.transmitters.len(), site.transmitters.len());
        let [x0, y0, x1, y1] = v.bounds_m;
        assert!(x1 > x0 && y1 > y0, "{:?}", v.bounds_m);
        for t in &v.transmitters {
            assert!((x0..=x1).contains(&t.x_m) && (y0..=y1).contains(&t.y_m));
        }
    }
}

//! `[scene]`: which generator builds the world and its dimensions.

use crate::sim::checker::Checker;
use serde::{Deserialize, Serialize};

/// Which scene generator to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// A grid of building blocks separated by streets.
    Streets,
    /// One large open paved area ringed by buildings, with lamp posts and parked cars.
    ParkingLot,
}

/// Procedural scene parameters (scene frame: local ENU about the origin, metres).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneCfg {
    /// Generator.
    pub kind: SceneKind,
    /// Number of blocks along East / North (streets) or 1 x 1 (parking lot area).
    pub blocks: [u32; 2],
    /// Block size along East and North (m); for a parking lot, the open area's size.
    pub block_size_m: [f64; 2],
    /// Street width, kerb to kerb (m).
    pub street_width_m: f64,
    /// Sidewalk width (m).
    pub sidewalk_width_m: f64,
    /// Kerb height above the road (m).
    pub curb_height_m: f64,
    /// Ground slope dz/dEast and dz/dNorth (dimensionless).
    pub ground_slope: [f64; 2],
    /// Building height range (m).
    pub building_height_m: [f64; 2],
    /// Building frontage length range (m).
    pub building_length_m: [f64; 2],
    /// Largest yaw of a facade away from its street (deg).
    pub facade_max_skew_deg: f64,
    /// Pole (lamp post) spacing along sidewalks (m); 0 = none.
    pub pole_spacing_m: f64,
    /// Pole radius and height (m).
    pub pole_radius_m: f64,
    /// Pole height (m).
    pub pole_height_m: f64,
    /// Spherical targets per street side per block; 0 = none.
    pub spheres_per_side: u32,
    /// Spherical target radius (m).
    pub sphere_radius_m: f64,
    /// Flat retro-reflective sync targets per street side per block; 0 = none.
    pub sync_targets_per_side: u32,
    /// Trees per street side per block (porous sphere crowns on trunks); 0 = none.
    pub trees_per_side: u32,
    /// Probability that a ray passes through a tree crown.
    pub tree_porosity: f64,
    /// Parked cars per row (parking lot only).
    pub cars_per_row: u32,
    /// Spatial index cell size (m).
    pub grid_cell_m: f64,
    /// Diffuse reflectance of ground, facades, poles, spheres, trees (0..1).
    pub reflectance: [f64; 5],
    /// Reflectance of retro-reflective sync targets (>> 1 saturates the intensity).
    pub sync_reflectance: f64,
    /// Yaw of every sync target's face about the vertical, away from facing its street (deg).
    pub sync_target_yaw_deg: f64,
    /// When > 0, an unlisted retro-reflective plate (a sign, not a sync target) stands this
    /// far along the street beyond the first sync target (m).
    pub decoy_offset_m: f64,
    /// Share of each reference patch's returns that come from foreign things (objects in
    /// front of facades, stones on the ground squares, mixed returns at their edges), 0..0.05.
    pub foreign_share: f64,
}

impl Default for SceneCfg {
    fn default() -> Self {
        SceneCfg {
            kind: SceneKind::Streets,
            blocks: [2, 2],
            block_size_m: [100.0, 80.0],
            street_width_m: 12.0,
            sidewalk_width_m: 3.0,
            curb_height_m: 0.15,
            ground_slope: [0.0, 0.0],
            building_height_m: [8.0, 25.0],
            building_length_m: [12.0, 30.0],
            facade_max_skew_deg: 8.0,
            pole_spacing_m: 25.0,
            pole_radius_m: 0.1,
            pole_height_m: 6.0,
            spheres_per_side: 1,
            sphere_radius_m: 0.25,
            sync_targets_per_side: 1,
            trees_per_side: 0,
            tree_porosity: 0.4,
            cars_per_row: 10,
            grid_cell_m: 8.0,
            reflectance: [0.2, 0.5, 0.4, 0.8, 0.3],
            sync_reflectance: 50.0,
            sync_target_yaw_deg: 0.0,
            decoy_offset_m: 0.0,
            foreign_share: 0.0,
        }
    }
}

impl SceneCfg {
    /// Checks every value's range.
    pub(super) fn check(&self, c: &mut Checker) {
        c.test(
            "scene.blocks",
            self.blocks.iter().all(|&b| (1..=50).contains(&b)),
            || format!("each count must be 1..=50, got {:?}", self.blocks),
        );
        for (i, v) in self.block_size_m.iter().enumerate() {
            c.range(&format!("scene.block_size_m[{i}]"), *v, 20.0, 2000.0);
        }
        c.range("scene.street_width_m", self.street_width_m, 5.0, 100.0);
        c.range("scene.sidewalk_width_m", self.sidewalk_width_m, 0.5, 20.0);
        c.range("scene.curb_height_m", self.curb_height_m, 0.0, 0.5);
        c.finite("scene.ground_slope", &self.ground_slope);
        c.test(
            "scene.ground_slope",
            self.ground_slope.iter().all(|g| g.abs() <= 0.15),
            || {
                format!(
                    "each slope must be within +-0.15, got {:?}",
                    self.ground_slope
                )
            },
        );
        c.interval("scene.building_height_m", self.building_height_m);
        c.interval("scene.building_length_m", self.building_length_m);
        c.range(
            "scene.facade_max_skew_deg",
            self.facade_max_skew_deg,
            0.0,
            30.0,
        );
        c.nonneg("scene.pole_spacing_m", self.pole_spacing_m);
        c.range("scene.pole_radius_m", self.pole_radius_m, 0.01, 2.0);
        c.range("scene.pole_height_m", self.pole_height_m, 0.5, 50.0);
        c.range("scene.sphere_radius_m", self.sphere_radius_m, 0.02, 2.0);
        c.range("scene.tree_porosity", self.tree_porosity, 0.0, 1.0);
        c.range("scene.grid_cell_m", self.grid_cell_m, 1.0, 100.0);
        for (i, r) in self.reflectance.iter().enumerate() {
            c.range(&format!("scene.reflectance[{i}]"), *r, 0.0, 1.0);
        }
        c.range("scene.sync_reflectance", self.sync_reflectance, 0.0, 1000.0);
        c.range(
            "scene.sync_target_yaw_deg",
            self.sync_target_yaw_deg,
            -80.0,
            80.0,
        );
        c.range("scene.decoy_offset_m", self.decoy_offset_m, 0.0, 1000.0);
        c.range("scene.foreign_share", self.foreign_share, 0.0, 0.05);
    }
}

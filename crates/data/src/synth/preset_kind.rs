//! The names of the synthetic world's scenarios (`--preset`): what each one is for. The
//! worlds themselves are built in `preset` and, for the motion suite, in `suite`.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// A gentle bend, a mix of cars and pedestrians with non-linear motion.
    Urban,
    /// No moving objects (the ego camera still drives).
    Static,
    /// A tight bend (radius 15 m) the ego drives through.
    SharpTurn,
    /// An oncoming car at ~25 m/s that brakes.
    FastApproach,
    /// Small movers 50-130 m away.
    FarSmallMovers,
    /// A truck crossing the road close ahead, occluding the scene.
    CrossingTruck,
    /// Dusk: low sun, dark sky, dim ambient light.
    LowLight,
    /// A long bend of random radius (25-70 m, either side) the ego is already in at the
    /// first frame: every window turns, 0.4-2° per frame. The other presets turn only in
    /// a few windows, so their pose labels teach "no rotation" almost everywhere.
    Winding,
    /// The urban scene seen by a camera panning on its mount (±2-6°, period 1.2-2.5 s): the
    /// yaw rate changes from window to window whatever the road does, so no single frame's
    /// look tells it.
    LookAround,
    /// The look-around camera on an ego that stands still (waiting at a junction): the
    /// only camera motion is the pan, a pure rotation, and the translation is zero.
    StoppedPan,
    /// Motion suite (`suite`): movers at constant velocity, the control.
    MotionConstant,
    /// Motion suite: movers braking and accelerating.
    MotionAccelerating,
    /// Motion suite: movers turning on arcs.
    MotionTurning,
    /// Motion suite: movers crossing the road ahead.
    MotionCrossing,
    /// Motion suite: stop-and-go traffic.
    MotionStopAndGo,
}

impl Preset {
    pub const ALL: [Preset; 15] = [
        Preset::Urban,
        Preset::Static,
        Preset::SharpTurn,
        Preset::FastApproach,
        Preset::FarSmallMovers,
        Preset::CrossingTruck,
        Preset::LowLight,
        Preset::Winding,
        Preset::LookAround,
        Preset::StoppedPan,
        Preset::MotionConstant,
        Preset::MotionAccelerating,
        Preset::MotionTurning,
        Preset::MotionCrossing,
        Preset::MotionStopAndGo,
    ];
    /// The motion suite (`suite`): one motion type each, simple ego motion.
    pub const MOTION_SUITE: [Preset; 5] = [
        Preset::MotionConstant,
        Preset::MotionAccelerating,
        Preset::MotionTurning,
        Preset::MotionCrossing,
        Preset::MotionStopAndGo,
    ];
    pub fn name(&self) -> &'static str {
        match self {
            Preset::Urban => "urban",
            Preset::Static => "static",
            Preset::SharpTurn => "sharp-turn",
            Preset::FastApproach => "fast-approach",
            Preset::FarSmallMovers => "far-small-movers",
            Preset::CrossingTruck => "crossing-truck",
            Preset::LowLight => "low-light",
            Preset::Winding => "winding",
            Preset::LookAround => "look-around",
            Preset::StoppedPan => "stopped-pan",
            Preset::MotionConstant => "motion-constant",
            Preset::MotionAccelerating => "motion-accelerating",
            Preset::MotionTurning => "motion-turning",
            Preset::MotionCrossing => "motion-crossing",
            Preset::MotionStopAndGo => "motion-stop-and-go",
        }
    }
    pub fn from_name(name: &str) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.name() == name)
    }
}

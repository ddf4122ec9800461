//! `softcbf identify`: stiffness, damping and actuator gains from the robot's own logs
//! (paper §V; docs/model.md §9), by least squares on the equation of motion.

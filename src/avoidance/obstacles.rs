//! The obstacle cost: keep selected links of the robot away from world obstacles ([theory §4](crate::theory#s4), a cost `h` for [\[M18\]](crate::theory#m18)).
//!
//! For every selected pair `k` of a link collision shape and an obstacle, with signed distance `d_k(q)` (m, negative
//! when penetrating) and influence distance `d_i,k > 0` (m):
//!
//! ```text
//! h(q)  = ½ Σ_k δ_k² / d_i,k ,    δ_k = d_i,k − d_k(q)  if d_k < d_i,k ,   0 otherwise
//! ∇h(q) = Σ_k (δ_k / d_i,k) J_p,kᵀ n_k
//! ```
//!
//! the form of the joint-limit cost [\[M20\]](crate::theory#m20) with the distance in place of the joint position: zero, with a zero
//! gradient, beyond the influence distance, C¹ across it, and still growing (and defined) when the shapes penetrate.
//! `h` is in metres, like the prismatic terms of [\[M20\]](crate::theory#m20), so one removal threshold `h_max` ([D6](crate::theory#d6)) serves both costs.
//! The gradient follows from `∂d_k/∂q = −n_kᵀ J_p,k(q)`: `n_k` is the unit normal from the link shape towards the
//! obstacle at the closest points, `J_p,k` the point Jacobian (base frame) of the link's witness point, a point fixed
//! on the link. (At a configuration where the closest points are not unique — parallel faces — `d` is only
//! directionally differentiable and this is one of its subgradients.)
//!
//! The link shapes come from the URDF `<collision>` elements ([`LinkColliders`]); a link with several elements gives
//! one pair per element. Far pairs cost one parry query each with the influence distance as cut-off (no closest-point
//! computation), and the forward kinematics runs once per evaluation, on the stack: evaluation allocates nothing while
//! no shape penetrates an obstacle.

use super::collision::{proximity, signed_distance, Collider, Geometry};
use super::{checked_cost, Cost, CostError, MeshPaths};
use crate::math::{first_non_finite, JointVector};
use crate::robot::{parse_urdf, ChainLink, KinematicState, KinematicsWorkspace, SerialChain};
use nalgebra::{Isometry3, SMatrix};

/// The collision shapes of the links of a chain, read from URDF `<collision>` elements.
///
/// Each shape is carried by a link of the chain ([`SerialChain::links`]), its pose expressed in that link's frame. A
/// link off the chain but rigidly attached to it by fixed joints (a camera or tool link beyond the tip) has its shapes
/// carried by the chain link it hangs from, and pairs may name it.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkColliders {
    colliders: Vec<LinkCollider>,
}

#[derive(Debug, Clone, PartialEq)]
struct LinkCollider {
    /// The link the shape belongs to.
    link: String,
    /// The chain link that carries it.
    carrier: String,
    /// The shape, posed in the carrier's frame.
    collider: Collider,
}

impl LinkColliders {
    /// The `<collision>` elements of the links on `chain`'s path and of the links attached to them by fixed joints,
    /// from the URDF text the chain was loaded from. Other links are ignored.
    ///
    /// Mesh files are found as [`MeshPaths::new`] says, relative paths against the working directory; see
    /// [`LinkColliders::from_urdf_robot_with_meshes`] to give the URDF's directory and package directories.
    ///
    /// # Errors
    /// [`CostError::Robot`] for unparsable URDF, [`CostError::InvalidGeometry`] for a non-positive or non-finite size
    /// or pose, and the mesh errors of [`LinkColliders::from_urdf_robot_with_meshes`].
    pub fn from_urdf_str<const N: usize>(
        xml: &str,
        chain: &SerialChain<N>,
    ) -> Result<Self, CostError> {
        Self::from_urdf_robot(&parse_urdf(xml)?, chain)
    }

    /// As [`LinkColliders::from_urdf_str`], from a parsed urdf-rs robot.
    ///
    /// # Errors
    /// As [`LinkColliders::from_urdf_str`] without the parse error.
    pub fn from_urdf_robot<const N: usize>(
        robot: &urdf_rs::Robot,
        chain: &SerialChain<N>,
    ) -> Result<Self, CostError> {
        Self::from_urdf_robot_with_meshes(robot, chain, &MeshPaths::new(""))
    }

    /// As [`LinkColliders::from_urdf_robot`], with the mesh files of `<mesh>` elements found through `meshes`; each
    /// mesh is read once, here, and becomes the convex hull of its vertices ([D20](crate::theory#d20)).
    ///
    /// # Errors
    /// As [`LinkColliders::from_urdf_robot`]; for meshes, each naming the link and the file:
    /// [`CostError::UnknownPackage`], [`CostError::MeshFile`] (missing or unreadable), [`CostError::MalformedMesh`],
    /// [`CostError::UnsupportedGeometry`] (a format other than STL, OBJ and COLLADA), [`CostError::DegenerateConvexHull`].
    pub fn from_urdf_robot_with_meshes<const N: usize>(
        robot: &urdf_rs::Robot,
        chain: &SerialChain<N>,
        meshes: &MeshPaths,
    ) -> Result<Self, CostError> {
        // (link, carrier chain link, carrier_from_link): the chain links, then whatever fixed joints attach to them.
        let mut attached: Vec<(String, String, Isometry3<f64>)> = chain
            .links()
            .iter()
            .map(|l| {
                (
                    l.name().to_owned(),
                    l.name().to_owned(),
                    Isometry3::identity(),
                )
            })
            .collect();
        let mut next = 0;
        while let Some((parent, carrier, carrier_from_parent)) = attached.get(next).cloned() {
            next += 1;
            for joint in &robot.joints {
                let child = &joint.child.link;
                if joint.parent.link == parent
                    && joint.joint_type == urdf_rs::JointType::Fixed
                    && !attached.iter().any(|(name, _, _)| name == child)
                {
                    let origin = urdf_pose(&joint.name, &joint.origin)?;
                    attached.push((child.clone(), carrier.clone(), carrier_from_parent * origin));
                }
            }
        }
        let mut colliders = Vec::new();
        for (link, carrier, carrier_from_link) in &attached {
            let Some(urdf_link) = robot.links.iter().find(|l| &l.name == link) else {
                continue;
            };
            for collision in &urdf_link.collision {
                let geometry = Geometry::from_urdf(link, &collision.geometry, meshes)?;
                let origin = urdf_pose(link, &collision.origin)?;
                colliders.push(LinkCollider {
                    link: link.clone(),
                    carrier: carrier.clone(),
                    collider: Collider::new(link, geometry, carrier_from_link * origin)?,
                });
            }
        }
        Ok(Self { colliders })
    }

    /// Colliders given explicitly, as `(link name, collider in the link frame)`.
    ///
    /// # Errors
    /// [`CostError::UnknownLink`] for a link not on the chain.
    pub fn new<const N: usize>(
        chain: &SerialChain<N>,
        colliders: impl IntoIterator<Item = (String, Collider)>,
    ) -> Result<Self, CostError> {
        let colliders = colliders
            .into_iter()
            .map(|(link, collider)| match chain.link(&link) {
                Some(_) => Ok(LinkCollider {
                    carrier: link.clone(),
                    link,
                    collider,
                }),
                None => Err(CostError::UnknownLink { link }),
            })
            .collect::<Result<_, CostError>>()?;
        Ok(Self { colliders })
    }

    /// The colliders of one link, each with the name of the chain link that carries it (posed in that link's frame).
    pub fn of_link<'s>(
        &'s self,
        link: &'s str,
    ) -> impl Iterator<Item = (&'s str, &'s Collider)> + 's {
        self.colliders
            .iter()
            .filter(move |c| c.link == link)
            .map(|c| (c.carrier.as_str(), &c.collider))
    }

    /// The number of colliders.
    pub fn len(&self) -> usize {
        self.colliders.len()
    }

    /// `true` without any collider.
    pub fn is_empty(&self) -> bool {
        self.colliders.is_empty()
    }
}

/// A URDF `<origin>` (`xyz`, then `rpy` about fixed axes: `R = Rz(yaw) Ry(pitch) Rx(roll)`).
fn urdf_pose(owner: &str, pose: &urdf_rs::Pose) -> Result<Isometry3<f64>, CostError> {
    if let Some(&value) = pose
        .xyz
        .iter()
        .chain(pose.rpy.iter())
        .find(|v| !v.is_finite())
    {
        return Err(CostError::InvalidGeometry {
            owner: owner.to_owned(),
            field: "origin",
            value,
        });
    }
    Ok(Isometry3::from_parts(
        nalgebra::Translation3::new(pose.xyz[0], pose.xyz[1], pose.xyz[2]),
        nalgebra::UnitQuaternion::from_euler_angles(pose.rpy[0], pose.rpy[1], pose.rpy[2]),
    ))
}

/// A world obstacle: a named shape with its pose in the robot base frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    name: String,
    collider: Collider,
}

impl Obstacle {
    /// An obstacle `name` of `geometry` at `base_from_shape` (pose in the robot base frame).
    ///
    /// # Errors
    /// [`CostError::InvalidGeometry`].
    pub fn new(
        name: &str,
        geometry: Geometry,
        base_from_shape: Isometry3<f64>,
    ) -> Result<Self, CostError> {
        Ok(Self {
            name: name.to_owned(),
            collider: Collider::new(name, geometry, base_from_shape)?,
        })
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its shape and pose in the base frame.
    pub fn collider(&self) -> &Collider {
        &self.collider
    }
}

/// A selected (link, obstacle) pair and its influence distance `d_i` (m, > 0).
#[derive(Debug, Clone, PartialEq)]
pub struct ObstaclePair {
    /// The link name (on the chain, with collision geometry).
    pub link: String,
    /// The obstacle name.
    pub obstacle: String,
    /// `d_i` (m): the cost is zero when the link is farther than this from the obstacle.
    pub influence_distance: f64,
}

/// One (link collider, obstacle) term, preallocated.
#[derive(Debug, Clone, PartialEq)]
struct Term {
    /// The chain link that carries the shape.
    link: ChainLink,
    /// The name of the link the shape belongs to (the carrier or a link fixed to it).
    name: String,
    collider: Collider,
    obstacle: usize,
    obstacle_collider: Collider,
    influence: f64,
}

/// The closest (link, obstacle) pair at a configuration, and its signed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPair<'a> {
    /// The link.
    pub link: &'a str,
    /// The obstacle.
    pub obstacle: &'a str,
    /// Their signed distance (m; negative when penetrating).
    pub distance: f64,
}

/// The obstacle cost of the [module docs](self), a [`Cost`] named `"obstacles"`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObstacleCost<const N: usize> {
    chain: SerialChain<N>,
    obstacles: Vec<Obstacle>,
    terms: Vec<Term>,
}

impl<const N: usize> ObstacleCost<N> {
    /// The cost of the `pairs` between the links of `chain` (shapes from `links`) and `obstacles`.
    ///
    /// # Errors
    /// [`CostError::UnknownLink`] (not on the chain), [`CostError::NoCollisionGeometry`],
    /// [`CostError::UnknownObstacle`], [`CostError::InvalidInfluenceDistance`] (not finite and > 0).
    pub fn new(
        chain: SerialChain<N>,
        links: &LinkColliders,
        obstacles: Vec<Obstacle>,
        pairs: &[ObstaclePair],
    ) -> Result<Self, CostError> {
        let mut terms = Vec::new();
        for pair in pairs {
            let unknown = || CostError::UnknownLink {
                link: pair.link.clone(),
            };
            if chain.link(&pair.link).is_none() && links.of_link(&pair.link).next().is_none() {
                return Err(unknown());
            }
            let obstacle = obstacles
                .iter()
                .position(|o| o.name == pair.obstacle)
                .ok_or_else(|| CostError::UnknownObstacle {
                    obstacle: pair.obstacle.clone(),
                })?;
            let influence = pair.influence_distance;
            if !(influence.is_finite() && influence > 0.0) {
                return Err(CostError::InvalidInfluenceDistance {
                    link: pair.link.clone(),
                    obstacle: pair.obstacle.clone(),
                    value: influence,
                });
            }
            let before = terms.len();
            let obstacle_collider = obstacles[obstacle].collider.clone();
            for (carrier, collider) in links.of_link(&pair.link) {
                terms.push(Term {
                    link: chain.link(carrier).ok_or_else(unknown)?.clone(),
                    name: pair.link.clone(),
                    collider: collider.clone(),
                    obstacle,
                    obstacle_collider: obstacle_collider.clone(),
                    influence,
                });
            }
            if terms.len() == before {
                return Err(CostError::NoCollisionGeometry {
                    link: pair.link.clone(),
                });
            }
        }
        Ok(Self {
            chain,
            obstacles,
            terms,
        })
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// The number of (link collider, obstacle) terms.
    pub fn term_count(&self) -> usize {
        self.terms.len()
    }

    /// The closest pair at `q` and its exact signed distance (no cut-off), or `None` without pairs. For monitoring
    /// (simulation outcomes, reports); may allocate when shapes penetrate.
    ///
    /// # Errors
    /// Non-finite `q`.
    pub fn closest_pair(&self, q: &JointVector<N>) -> Result<Option<ClosestPair<'_>>, CostError> {
        let mut workspace = KinematicsWorkspace::new();
        let state = self.kinematics(&mut workspace, q)?;
        let mut closest: Option<ClosestPair<'_>> = None;
        for term in &self.terms {
            let distance = signed_distance(
                &term.collider,
                &state.base_from_link(&term.link)?,
                &term.obstacle_collider,
                &Isometry3::identity(),
            )?;
            if closest.is_none_or(|c| distance < c.distance) {
                closest = Some(ClosestPair {
                    link: &term.name,
                    obstacle: self
                        .obstacles
                        .get(term.obstacle)
                        .map_or("", |o| o.name.as_str()),
                    distance,
                });
            }
        }
        Ok(closest)
    }

    fn kinematics<'w>(
        &self,
        workspace: &'w mut KinematicsWorkspace<N>,
        q: &JointVector<N>,
    ) -> Result<&'w KinematicState<N>, CostError> {
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(CostError::NonFiniteConfiguration { joint, value });
        }
        Ok(self.chain.kinematics(workspace, q)?)
    }

    /// `h(q)` and, when asked, `∇h(q)`.
    fn evaluate(
        &self,
        q: &JointVector<N>,
        mut gradient: Option<&mut JointVector<N>>,
    ) -> Result<f64, CostError> {
        // KinematicsWorkspace is a fixed-size struct without heap storage: this is stack memory.
        let mut workspace = KinematicsWorkspace::new();
        let state = self.kinematics(&mut workspace, q)?;
        if let Some(g) = gradient.as_deref_mut() {
            g.fill(0.0);
        }
        let mut point_jacobian = SMatrix::<f64, 3, N>::zeros();
        let mut value = 0.0;
        for term in &self.terms {
            let Some(p) = proximity(
                &term.collider,
                &state.base_from_link(&term.link)?,
                &term.obstacle_collider,
                &Isometry3::identity(),
                term.influence,
            )?
            else {
                continue;
            };
            let delta = term.influence - p.distance;
            if delta <= 0.0 {
                continue;
            }
            value += 0.5 * delta * delta / term.influence;
            if let Some(g) = gradient.as_deref_mut() {
                state.point_jacobian(&term.link, &p.point_on_first, &mut point_jacobian)?;
                // ∂h/∂q = −(δ/d_i) ∂d/∂q = (δ/d_i) nᵀ J_p.
                g.gemv_tr(delta / term.influence, &point_jacobian, &p.normal, 1.0);
            }
        }
        checked_cost(Cost::<N>::name(self), value, gradient.as_deref())
    }
}

impl<const N: usize> Cost<N> for ObstacleCost<N> {
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        self.evaluate(q, None)
    }

    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        self.evaluate(q, Some(gradient))
    }

    fn name(&self) -> &str {
        "obstacles"
    }
}

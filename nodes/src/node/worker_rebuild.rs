//! What rebuilds a worker's logic around a new robot: a URDF on `robot_description`, and a
//! payload from `~/set_payload` or a run-time set of `payload.*`. The state is carried over;
//! the current logic stays in use when the rebuild fails. A service call's payload holds until
//! the next `payload.*` parameter set.

use constraint_dynamics::model::Payload;

use super::{NodeLogic, Reply, Worker};
use crate::msg::constraint_dynamics_msgs::srv::{SetPayloadRequest, SetPayloadResponse};
use crate::msg::diagnostic_msgs::KeyValue;
use crate::params::NodeParams;

/// The payload of a `SetPayload` request; errors name the request's field.
pub(crate) fn payload_of_request(req: &SetPayloadRequest) -> Result<Payload, String> {
    let i = &req.inertia;
    if req.frame.trim().is_empty() && i.m != 0.0 {
        return Err(format!(
            "frame: empty, but inertia.m = {} kg: name the frame that carries the payload",
            i.m
        ));
    }
    let p = Payload {
        frame: req.frame.clone(),
        mass: i.m,
        com: [i.com.x, i.com.y, i.com.z],
        inertia: [i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz],
    };
    p.validate().map_err(|e| request_fields(&e.to_string()))?;
    Ok(p)
}

/// The core names the scene's fields (`payload.mass`); a request's are `inertia.m`, ….
fn request_fields(message: &str) -> String {
    message
        .replace("payload.frame", "frame")
        .replace("payload.mass", "inertia.m")
        .replace("payload.com", "inertia.com")
        .replace("payload.inertia", "inertia (ixx, ixy, ixz, iyy, iyz, izz)")
}

impl<N: NodeLogic> Worker<N> {
    /// `~/set_payload`, a panic caught (the logic then rebuilt from its scene): replies and
    /// returns whether the payload was set.
    pub(super) fn serve_set_payload(
        &mut self,
        req: &SetPayloadRequest,
        reply: Reply<SetPayloadResponse>,
    ) -> bool {
        let mut response = None;
        self.guarded("set_payload", |w| {
            response = Some(w.set_payload(req));
            false
        });
        let response = response.unwrap_or_else(|| SetPayloadResponse {
            success: false,
            message: "internal error while rebuilding the model (see the node's log); the \
                      payload in use is unchanged"
                .into(),
        });
        let success = response.success;
        let _ = reply.try_send(response);
        success
    }

    /// The `/diagnostics` value of the payload in use.
    pub(super) fn payload_status(&self) -> KeyValue {
        KeyValue {
            key: "payload".into(),
            value: self.logic.robot().payload().describe(),
        }
    }

    /// The logic rebuilt with the request's payload, or the reason it was not.
    fn set_payload(&mut self, req: &SetPayloadRequest) -> SetPayloadResponse {
        let refused = |message: String| SetPayloadResponse {
            success: false,
            message,
        };
        let payload = match payload_of_request(req) {
            Ok(p) => p,
            Err(e) => return refused(e),
        };
        let params = self.logic.params().clone();
        match self.rebuilt_with(&payload, params) {
            Ok(()) => SetPayloadResponse {
                success: true,
                message: format!("payload in use: {}", payload.describe()),
            },
            Err(e) => refused(request_fields(&e)),
        }
    }

    /// New parameters (run-time set): a changed `payload.*` rebuilds the logic.
    pub(super) fn params_changed(&mut self, params: NodeParams<N::Params>) {
        self.log.info("parameters changed");
        if params.common.payload != self.logic.params().common.payload {
            self.payload_params(params);
        } else {
            self.logic.set_params(params);
        }
    }

    /// Rebuilds the model from a URDF; true if it changed.
    pub(super) fn robot_description(&mut self, urdf: &str) -> bool {
        let params = self.logic.params().clone();
        let next = self
            .logic
            .robot()
            .with_urdf(urdf, &params.common)
            .and_then(|robot| N::new(robot, params, self.log.clone()));
        match next {
            Ok(next) => {
                let m = next.robot().model();
                self.log.info(&format!(
                    "model rebuilt from robot_description: '{}', nq = {}, nv = {}",
                    m.name, m.nq, m.nv
                ));
                self.logic = next;
                true
            }
            Err(e) => {
                let message = format!("robot_description refused, keeping the current model: {e}");
                self.log.error(&message);
                self.health.error(message);
                false
            }
        }
    }

    /// A run-time set of `payload.*`: the parameters' payload (the scene's when they name
    /// none) replaces the one in use, a service call's included.
    fn payload_params(&mut self, params: NodeParams<N::Params>) {
        let payload = match params.common.payload.payload() {
            Ok(Some(p)) => p,
            Ok(None) => self.logic.robot().scene().file.payload.clone(),
            // Validated before it was sent; kept for a clear line if that ever changes.
            Err(e) => {
                self.log.error(&format!("payload parameters refused: {e}"));
                self.logic.set_params(params);
                return;
            }
        };
        if let Err(e) = self.rebuilt_with(&payload, params.clone()) {
            let message = format!("payload parameters not applied, keeping the model: {e}");
            self.log.error(&message);
            self.health.error(message);
            self.logic.set_params(params);
        }
    }

    /// Replaces the logic by one built around the robot carrying `payload`; on an error the
    /// current logic stays.
    fn rebuilt_with(
        &mut self,
        payload: &Payload,
        params: NodeParams<N::Params>,
    ) -> Result<(), String> {
        let next = self
            .logic
            .robot()
            .with_payload(payload, &params.common)
            .and_then(|robot| N::new(robot, params, self.log.clone()))
            .map_err(|e| e.to_string())?;
        self.logic = next;
        self.log.info(&format!(
            "model rebuilt with payload: {} (total mass {:.6} kg)",
            payload.describe(),
            self.logic.robot().model().total_mass()
        ));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::geometry_msgs::{Inertia, Vector3};

    fn request(frame: &str, m: f64, ixx: f64) -> SetPayloadRequest {
        SetPayloadRequest {
            frame: frame.into(),
            inertia: Inertia {
                m,
                com: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 0.1,
                },
                ixx,
                iyy: 0.01,
                izz: 0.01,
                ..Default::default()
            },
        }
    }

    #[test]
    fn bad_requests_name_the_request_field() {
        for (req, field) in [
            (request("", 2.0, 0.01), "frame"),
            (request("tool0", -2.0, 0.01), "inertia.m"),
            (request("tool0", f64::NAN, 0.01), "inertia.m"),
            (request("tool0", 2.0, 0.05), "inertia (ixx"),
            (request("tool0", 2.0, -0.01), "inertia (ixx"),
        ] {
            let e = payload_of_request(&req).unwrap_err();
            assert!(e.starts_with(field), "{field}: {e}");
        }
        let p = payload_of_request(&request("tool0", 2.0, 0.01)).unwrap();
        assert_eq!((p.mass, p.com, p.inertia[0]), (2.0, [0.0, 0.0, 0.1], 0.01));
        // Mass 0: no payload, on any frame or none.
        assert!(
            payload_of_request(&request("", 0.0, 0.0))
                .unwrap()
                .is_none()
        );
    }
}

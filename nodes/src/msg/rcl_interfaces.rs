//! `rcl_interfaces/srv/*` parameter services, as markers over ros2-client's own request and
//! response types (ros2-client serves them on every node; these are for clients such as the
//! tests and `constraint_dynamics_query`).

use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParametersRequest,
    GetParametersResponse, ListParametersRequest, ListParametersResponse, SetParametersRequest,
    SetParametersResponse,
};

use super::RosService;

macro_rules! parameter_service {
    ($srv:ident, $req:ty, $resp:ty) => {
        #[doc = concat!("Marker for `rcl_interfaces/srv/", stringify!($srv), "`.")]
        #[derive(Clone, Copy, Debug)]
        pub struct $srv;
        impl RosService for $srv {
            type Request = $req;
            type Response = $resp;
            const PACKAGE: &'static str = "rcl_interfaces";
            const NAME: &'static str = stringify!($srv);
        }
    };
}

parameter_service!(GetParameters, GetParametersRequest, GetParametersResponse);
parameter_service!(
    ListParameters,
    ListParametersRequest,
    ListParametersResponse
);
parameter_service!(SetParameters, SetParametersRequest, SetParametersResponse);
parameter_service!(
    DescribeParameters,
    DescribeParametersRequest,
    DescribeParametersResponse
);

// The MesoRenderer's parameters (backend_vulkan/src/meso_renderer.cpp, GpuMesoParams), read by
// plane.vert, base.vert and meso.frag. The maps are bindings 0..4 (march.glsl); the base mesh
// (FrameMesh corners, three a triangle) is binding 6, the images (the albedo's MesoAlbedo::words, then the normal map's) binding 7.
layout(std430, set = 0, binding = 5) readonly buffer MesoParams {
    mat4 viewProj;
    vec4 eye;           // world
    vec4 light;         // unit direction towards the light (world = tangent space), w: ambient
    vec4 voxelsPerUnit; // plane: (W / tile, H / tile, L / depth), base mesh: (W, H, L / depth); w: checker period in voxels
    vec4 plane;         // (half size of the plane in world units, quads per side, 0, 0)
    vec4 background;
    ivec4 dims0;        // width, height, layers, block
    ivec4 dims1;        // gx, gy, gz, coneM
    ivec4 dims2;        // coneN, the normal map's first word in the images, the part (MesoPart) drawn, 0
    vec4 tol;           // x: mesoRootTolerance<float>(), y: shadow-ray offset (voxels), z: normal-map scale, w: its greenT (kern::dmNormalMapTangent)
} params;

// One corner of the base mesh (backend_vulkan/src/meso_renderer.cpp, GpuFrameVertex).
struct DmFrameVertex {
    vec4 position; // xyz, w: s
    vec4 pS;       // dP/ds, w: t
    vec4 pT;       // dP/dt
    vec4 normal;   // unit
    vec4 shape;    // the second fundamental form in (s, t): n . P_ss, n . P_st, n . P_tt; w: the most convex principal curvature (FrameVertex::shape)
};
layout(std430, set = 0, binding = 6) readonly buffer FrameVertices { DmFrameVertex frameVertices[]; };

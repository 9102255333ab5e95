#version 450
// The MesoRenderer's fragment shader: the pixel's view ray into voxel space (Donnelly's
// normalisation, dmTangentToVoxel; on a base mesh first into the pixel's interpolated frame,
// dmFrameCoordinates), the marcher the specialisation constants choose (only that one
// survives specialisation), the shading with the height field's normal and, only when asked
// for, a shadow ray through the DDM's shadow cones; the colour is the albedo image's at the hit
// (trilinear over its mips, the level from the pixel's footprint) or a checker; the shading
// normal is the height field's or, when the scene has one, the normal map's at the hit
// (trilinear in the same way, dmNormalMapTangent, on the pixel's frame); a solid (non-height-
// field detail) is marched through its DDM and triangles, shaded with its corner normals
// (dmMesoSolidNormal, dmFrameVoxelNormal) and shadowed by the same march. On a base mesh the
// depth is the hit's (dmFramePoint), so the detail occludes and is occluded where it is, and a ray that misses
// (it leaves through the top, e.g. from a back face) writes the far plane: what lies behind
// it shows through; with kSilhouettes so does a hit past the point where the ray leaves the
// curved shell (dmShellExit on the interpolated second fundamental form); with kBentRays every
// marcher (the distance map, the DDM of a height field or a solid, relief mapping, POM) marches
// the view ray bent by that curvature in the slab's own coordinates (it then leaves the shell
// by itself). Every formula is a kernel (kernels/meso.h, kernels/meso_shade.h);
// march.glsl holds the loops.
#extension GL_GOOGLE_include_directive : require
#define DM_MESO_SET 0
#define DM_MESO_BINDING 0
#define DM_MESO_IMAGE_BINDING 7
#define DM_MESO_SOLID_BINDING 8
#include "march.glsl"
#include "meso_shade.glsl"
#include "common.glsl"

layout(constant_id = 0) const int kMethod = 1;     // MesoMethod: 0 distance map, 1 DDM, 2 relief, 3 POM
layout(constant_id = 1) const int kIterations = 64;
layout(constant_id = 2) const float kEps = -1.0;
layout(constant_id = 3) const bool kQuadrics = true;
layout(constant_id = 4) const int kExitRule = 1;
layout(constant_id = 5) const int kLinear = 32;
layout(constant_id = 6) const int kBinary = 6;
layout(constant_id = 7) const bool kShadows = false;
layout(constant_id = 8) const int kShadowIterations = 64;
layout(constant_id = 9) const int kBase = 0;            // 0 the plane z = 0, 1 a base mesh (base.vert)
layout(constant_id = 10) const bool kAlbedo = false;    // the albedo image (binding 7), else the checker
layout(constant_id = 11) const bool kNormalMap = false; // the normal map (binding 7 from params.dims2.y on) shades, else the height field's normal
layout(constant_id = 12) const bool kSolid = false;     // a non-height-field solid (bindings 8, 9): its DDM march (kMethod 1) and corner normals
layout(constant_id = 13) const bool kSilhouettes = false; // on a base mesh: hits past where the ray leaves the curved shell are misses (dmShellExit)
layout(constant_id = 14) const bool kBentRays = false;  // on a base mesh: the view ray bent by the base's curvature (dmMesoMarchDistanceBent, dmMesoMarchDdmBent, dmMesoMarchHeightBent)

layout(location = 0) in vec3 worldPos;
layout(location = 1) in vec2 tex;
layout(location = 2) in vec3 framePS;
layout(location = 3) in vec3 framePT;
layout(location = 4) in vec3 frameN;
layout(location = 5) in vec4 frameShape;
layout(location = 0) out vec4 outColor;
layout(location = 1) out vec4 outHit;    // voxel-space hit point, t (w = -1: the ray missed)
layout(location = 2) out vec4 outOrigin; // the view ray in voxel space: o, the curve of its bend (kBentRays; else 0)
layout(location = 3) out vec4 outDir;    // d, the bend (kBentRays; else 0)
layout(location = 4) out uvec4 outCounts; // view iterations, shadow iterations, shadowed + 2 x the part, hit (1; 2: a hit past the shell's exit, a miss)

void main() {
    DmMesoSize s;
    s.width = params.dims0.x;
    s.height = params.dims0.y;
    s.layers = params.dims0.z;
    s.block = params.dims0.w;
    s.gx = params.dims1.x;
    s.gy = params.dims1.y;
    s.gz = params.dims1.z;
    s.coneM = params.dims1.w;
    s.coneN = params.dims2.x;
    s.tol = params.tol.x;
    vec3 vpu = params.voxelsPerUnit.xyz;
    vec3 n0 = frameN * (1.0 / sqrt(dmDot3(frameN, frameN)));
    vec3 o;
    vec3 d;
    if (kBase == 0) {
        o = dmMesoEntry(worldPos, vpu, s.layers);
        d = dmTangentToVoxel(worldPos - params.eye.xyz, vpu);
    } else {
        o = dmMesoEntry(vec3(tex, 0.0), vpu, s.layers);
        d = dmTangentToVoxel(dmFrameCoordinates(worldPos - params.eye.xyz, framePS, framePT, n0), vpu);
    }
    // The footprint of the pixel in the texture (tiles), for the albedo's mip level: the
    // entry's texture coordinate differentiated here, in uniform control flow.
    vec2 uvEntry = vec2(o.x / float(s.width), o.y / float(s.height));
    vec2 uvDx = dFdx(uvEntry);
    vec2 uvDy = dFdy(uvEntry);
    DmMesoHit h;
    int entry = -1; // the solid's triangle hit (-1: the floor, or none)
    vec2 bary = vec2(0.0);
    float bend = 0.0;           // the view ray's bend (kBentRays)
    // The base's curvature where the slab reads it, limited to half its depth (dmShellLimit; 0.5: kShellCurvatureLimit).
    vec4 shell = dmShellLimit(frameShape, vpu, float(s.layers), 0.5);
    // The most convex curvature in voxels: how the bent ray's depth follows the quadric (dmBentPoint).
    float curve = kBentRays && kBase != 0 ? dmShellVoxels(shell, vpu).w : 0.0;
    vec3 bentPoint = vec3(0.0); // its hit in the slab's coordinates
    if (kBase != 0 && !(d.z < 0.0)) {
        // Seen from below the base (a back face): the ray leaves through the top at once.
        h.hit = false;
        h.t = 0.0;
        h.iterations = 0;
    } else if (kMethod == 0 && kBentRays && kBase != 0) {
        bend = dmShellBend(d, shell, vpu);
        h = dmMarchDistanceMapBent(s, o, d, bend, curve, kIterations, kEps, bentPoint);
    } else if (kMethod == 0) {
        h = dmMarchDistanceMap(s, o, d, kIterations, kEps);
    } else if (kMethod == 1 && kBentRays && kBase != 0) {
        bend = dmShellBend(d, shell, vpu);
        DmMesoSolidHit sh = dmMarchDdmBent(s, o, d, bend, curve, kIterations, kQuadrics, kSolid, kExitRule, 0.05, bentPoint); // 0.05: kMesoChordError
        h = sh.h;
        entry = sh.triangle;
        bary = sh.uv;
    } else if (kMethod == 1 && kSolid) {
        DmMesoSolidHit sh = dmMarchDdmSolid(s, o, d, kIterations, kExitRule);
        h = sh.h;
        entry = sh.triangle;
        bary = sh.uv;
    } else if (kMethod == 1) {
        h = dmMarchDdm(s, o, d, kIterations, kQuadrics, kExitRule);
    } else if (kBentRays && kBase != 0) {
        bend = dmShellBend(d, shell, vpu);
        h = dmMarchHeightSearchBent(s, o, d, bend, curve, kLinear, kMethod == 3 ? -1 : kBinary, bentPoint);
    } else {
        h = dmMarchHeightSearch(s, o, d, kLinear, kMethod == 3 ? -1 : kBinary);
    }
    outOrigin = vec4(o, curve); // w <= 0 (the clear's 1: not covered)
    outDir = vec4(d, bend);
    uint part = uint(params.dims2.z) << 1u; // which of the renderer's mesostructures drew the pixel
    // The silhouette: a hit beyond the point where the ray has left the curved shell through
    // its top is not seen (the ray went on into what lies behind).
    uint cut = 0u;
    if (kBase != 0 && kSilhouettes && !kBentRays && h.hit) {
        float exitT = dmShellExit(o, d, o, shell, vpu, float(s.layers));
        if (exitT >= 0.0 && h.t > exitT) {
            h.hit = false;
            cut = 2u;
        }
    }
    if (!h.hit) {
        outColor = params.background;
        outHit = vec4(0.0, 0.0, 0.0, -1.0);
        outCounts = uvec4(uint(h.iterations), 0u, part, cut);
        // A miss writes the far plane; a cut one just in front of it, so that the record of the
        // cut (MesoImage::cut) is kept over the back faces and plain misses behind it, whatever
        // the order the triangles are drawn in, and still loses to any hit.
        gl_FragDepth = kBase == 0 ? gl_FragCoord.z : (cut != 0u ? 1.0 - 1.0 / 8388608.0 : 1.0);
        return;
    }
    vec3 onRay = o + d * h.t;                  // where the straight ray is at the hit: the world point
    vec3 p = kBentRays ? bentPoint : onRay;    // where the detail is read
    vec3 axisS = kBase == 0 ? vec3(1.0, 0.0, 0.0) : framePS;
    vec3 axisT = kBase == 0 ? vec3(0.0, 1.0, 0.0) : framePT;
    vec3 axisN = kBase == 0 ? vec3(0.0, 0.0, 1.0) : n0;
    vec3 n;
    vec3 so; // the shadow ray's origin
    if (kSolid) {
        // The triangle's corner normals at the hit, turned to the ray's side (the floor's: up;
        // a bent ray's side is its direction there, dmBentTangent);
        // the shadow ray leaves along the face's own normal.
        vec3 nv = vec3(0.0, 0.0, 1.0);
        vec3 gv = nv;
        if (entry >= 0) {
            nv = dmMesoSolidNormal(entry, bary);
            gv = dmMesoSolidFacing(s, entry, kBentRays ? dmBentTangent(d, bend, curve, h.t) : d, nv);
        }
        n = dmFrameVoxelNormal(nv, axisS, axisT, axisN, vpu);
        so = p + gv * params.tol.y;
    } else {
        vec2 f;
        ivec2 c = dmHeightCell(vec2(p.x, p.y), f);
        vec4 cell = dmMesoCell(s, c.x, c.y);
        n = kBase == 0 ? dmMesoWorldNormal(cell, f, vpu) : dmFrameNormal(cell, f, framePS, framePT, n0, vpu);
        so = dmMesoShadowOrigin(p, cell, f, params.tol.y);
    }
    if (kBase == 0) {
        gl_FragDepth = gl_FragCoord.z;
    } else {
        vec4 clip = params.viewProj * vec4(dmFramePoint(worldPos, onRay, o, framePS, framePT, n0, vpu), 1.0);
        gl_FragDepth = clamp(clip.z / clip.w, 0.0, 1.0);
    }
    if (kNormalMap) {
        int image = params.dims2.y;
        float lod = dmMesoImageLod(uvDx, uvDy, vec2(float(dmMesoFetchImage(s, image + 2)), float(dmMesoFetchImage(s, image + 3))));
        vec3 nt = dmNormalMapTangent(dmMesoImage(s, image, vec2(p.x / float(s.width), p.y / float(s.height)), lod), params.tol.z, params.tol.w);
        n = kBase == 0 ? nt : dmFrameTangentNormal(nt, framePS, framePT, n0);
    }
    float lit = 1.0;
    uint shadowIterations = 0u;
    if (kShadows) {
        vec3 sd = kBase == 0 ? dmTangentToVoxel(params.light.xyz, vpu)
                             : dmTangentToVoxel(dmFrameCoordinates(params.light.xyz, framePS, framePT, n0), vpu);
        if (sd.z > 0.0) {
            DmMesoHit sh;
            if (kSolid) {
                sh = dmMarchDdmSolid(s, so, sd, kShadowIterations, 1).h;
            } else {
                sh = dmMarchDdm(s, so, sd, kShadowIterations, true, 1);
            }
            if (kBase != 0 && kSilhouettes && sh.hit) {
                // Past the shell's top the shadow ray is out in the open. The quadric is centred
                // where the slab's coordinates are the tangent plane's: the view ray's entry, or
                // with bent rays (the hit in the curved slab's own coordinates) the hit's column.
                vec3 centre = kBentRays ? vec3(so.x, so.y, float(s.layers)) : o;
                float exitT = dmShellExit(so, sd, centre, shell, vpu, float(s.layers));
                if (exitT >= 0.0 && sh.t > exitT) {
                    sh.hit = false;
                }
            }
            lit = sh.hit ? 0.0 : 1.0;
            shadowIterations = uint(sh.iterations);
        } else {
            lit = 0.0; // the base surface turns away from the light: its own shape shadows the point
        }
    }
    vec3 albedo;
    if (kAlbedo) {
        float lod = dmMesoImageLod(uvDx, uvDy, vec2(float(dmMesoFetchImage(s, 2)), float(dmMesoFetchImage(s, 3))));
        albedo = dmMesoImage(s, 0, vec2(p.x / float(s.width), p.y / float(s.height)), lod).rgb;
    } else {
        albedo = dmMesoChecker(vec2(p.x, p.y), params.voxelsPerUnit.w) * vec3(0.95, 0.85, 0.7);
    }
    outColor = vec4(albedo * dmMesoShade(1.0, n, params.light.xyz, params.light.w, lit), 1.0);
    outHit = vec4(p, h.t);
    outCounts = uvec4(uint(h.iterations), shadowIterations, (lit == 0.0 ? 1u : 0u) | part, 1u);
}

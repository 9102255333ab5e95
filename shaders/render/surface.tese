#version 450
// Tessellation evaluation (§5.3): the base surface s and its derivatives from the patch table
// (the Far patch containing (u, v) found through the face's quadtree), D with mip selection
// and blending (§6.2, §4.4 clamp), the displaced position f = s + N D. The fragment shader
// gets s_u, s_v, N (and N_u, N_v for accurate normals) to form the normal per pixel.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#ifdef DM_SPACING_INTEGER
layout(quads, equal_spacing, ccw) in;
#else
layout(quads, fractional_even_spacing, ccw) in;
#endif
layout(location = 0) patch in vec4 tcMip;
layout(location = 1) patch in int tcFace;

layout(location = 0) flat out int teFace;
layout(location = 1) out vec2 teUV;
layout(location = 2) out float teRho;
layout(location = 3) out vec3 teSu;
layout(location = 4) out vec3 teSv;
layout(location = 5) out vec3 teN;
layout(location = 6) out vec3 teNu;
layout(location = 7) out vec3 teNv;
layout(location = 8) out vec4 teEv;    // evNormal (xyz), evWeight
layout(location = 9) out vec3 teWorld;

void main() {
    int face = tcFace;
    vec2 uv = gl_TessCoord.xy;

    // The Far patch: down the face's quadtree (PackedSurface).
    uvec4 patchRec = findPatch(face, uv);
    uvec2 param = patchRec.zw;
    int count = int(patchRec.y);
    bool accurate = HAS_ACCURATE && (NORMALS == 1 || (NORMALS == 2 && faces[face].info.y != 0));

    float w[20];
    float wu[20];
    float wv[20];
    float wuu[20];
    float wuv[20];
    float wvv[20];
    vec3 p = vec3(0.0);
    vec3 su = vec3(0.0);
    vec3 sv = vec3(0.0);
    vec3 suu = vec3(0.0);
    vec3 suv = vec3(0.0);
    vec3 svv = vec3(0.0);
    // Second derivatives for accurate normals (N_u, N_v); otherwise only where s_u x s_v
    // vanishes, for the base normal's fallback. dmPatchBasis1's weights are dmPatchBasis2's,
    // bit for bit, so either route gives the same p, s_u, s_v.
    if (accurate) {
        dmPatchBasis2(param, count, uv, w, wu, wv, wuu, wuv, wvv);
    } else {
        dmPatchBasis1(param, count, uv, w, wu, wv);
    }
    for (int i = 0; i < count; ++i) {
        vec3 x = points[patchIndices[patchRec.x + uint(i)]].xyz;
        p += w[i] * x;
        su += wu[i] * x;
        sv += wv[i] * x;
    }
    vec3 n0 = cross(su, sv);
    bool degenerate = !(dmDot3(n0, n0) > 0.0);
    if (degenerate && !accurate) {
        dmPatchBasis2(param, count, uv, w, wu, wv, wuu, wuv, wvv);
    }
    if (accurate || degenerate) {
        for (int i = 0; i < count; ++i) {
            vec3 x = points[patchIndices[patchRec.x + uint(i)]].xyz;
            suu += wuu[i] * x;
            suv += wuv[i] * x;
            svv += wvv[i] * x;
        }
    }
    vec3 N = dmBaseNormal(su, sv, suu, suv, svv, uv, vec3(0.0, 0.0, 1.0));

    // §5.4 blend data of end caps at extraordinary corners.
    vec4 cw = dmEndCapCornerWeights(param, uv);
    vec4 ev = vec4(0.0);
    for (int c = 0; c < 4; ++c) {
        vec4 cn = cornerNormals[face * 4 + c];
        if (cn.w != 0.0 && cw[c] > 0.0) {
            ev += vec4(cw[c] * cn.xyz, cw[c]);
        }
    }

    float rho = 64.0;
    if (HAS_LOD) {
        float x = dmBilerp(tcMip, uv);
        rho = (LOD == 1 ? dmResolutionFromTessFactor(x) : x) - float(faces[face].info.x);
    }
    float D = 0.0;
    if (TECHNIQUE == 1) {
        D = sampleD1(face, uv, rho).x;
    } else if (TECHNIQUE == 2) {
        D = textureLod(baselineHeight, baselineUV(face, uv), 0.0).x;
    }
    vec3 Nu = vec3(0.0);
    vec3 Nv = vec3(0.0);
    if (accurate) {
        dmNormalDerivWeingarten(su, sv, suu, suv, svv, N, 1e-3, Nu, Nv);
    }
    vec3 f = p + N * D;

    if (HAS_CAPTURE) {
        uint slot = atomicAdd(captureCount, 1u);
        if (slot < uint(P.counts.y)) {
            captured[slot].position = vec4(f, rho);
            captured[slot].faceUV = vec4(float(face), uv, 0.0);
        }
    }
    teFace = face;
    teUV = uv;
    teRho = rho;
    teSu = su;
    teSv = sv;
    teN = N;
    teNu = Nu;
    teNv = Nv;
    teEv = ev;
    teWorld = f;
    gl_Position = P.viewProj * vec4(f, 1.0);
}

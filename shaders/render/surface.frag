#version 450
// Per-pixel normal (§5.3): D's derivatives at the pixel's (face, u, v) with the interpolated
// frame s_u, s_v, N (approximate, §5.2) plus the Weingarten term N_u D, N_v D (accurate,
// §5.1); across end-cap patches at extraordinary vertices interpolated from the patch's corners
// (§5.4, endCapNormal in common.glsl). The baseline
// decodes its tangent-space normal map instead; the base surface uses N. Built with
// DM_COLOR_ONLY: the colour output alone (an engine's target without a normal attachment).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
layout(location = 0) flat in int teFace;
layout(location = 1) in vec2 teUV;
layout(location = 2) in float teRho;
layout(location = 3) in vec3 teSu;
layout(location = 4) in vec3 teSv;
layout(location = 5) in vec3 teN;
layout(location = 6) in vec3 teNu;
layout(location = 7) in vec3 teNv;
layout(location = 8) in vec4 teEv;
layout(location = 9) in vec3 teWorld;
layout(location = 0) out vec4 outColor;
#ifndef DM_COLOR_ONLY
layout(location = 1) out vec4 outNormal; // world normal, 1 where covered
#endif

void main() {
    if (WIRE) {
        outColor = P.wireColor;
#ifndef DM_COLOR_ONLY
        outNormal = vec4(0.0);
#endif
        return;
    }
    vec3 N = dmSafeNormalize(teN, vec3(0.0, 0.0, 1.0));
    vec3 n = N;
    if (TECHNIQUE == 1) {
        vec2 uv = clamp(teUV, vec2(0.0), vec2(1.0));
        vec3 d1 = sampleD1(teFace, uv, teRho);
        vec3 fu;
        vec3 fv;
        bool accurate = HAS_ACCURATE && (NORMALS == 1 || (NORMALS == 2 && faces[teFace].info.y != 0));
        if (accurate) {
            n = dmDisplacedNormalAccurate(teSu, teSv, N, teNu, teNv, d1, fu, fv);
        } else {
            n = dmDisplacedNormalApprox(teSu, teSv, N, d1, fu, fv);
        }
        if (P.tess.w != 0.0) {
            // Faces with an extraordinary corner look their pixel's patch up (endCapNormal).
            if (cornerNormals[teFace * 4].w + cornerNormals[teFace * 4 + 1].w + cornerNormals[teFace * 4 + 2].w +
                    cornerNormals[teFace * 4 + 3].w > 0.0) {
                n = endCapNormal(teFace, uv, teRho, accurate, n);
            }
        } else if (teEv.w > 0.0) {
            n = dmBlendLimitNormal(n, teEv.xyz, teEv.w);
        }
    } else if (TECHNIQUE == 2) {
        vec2 uv = clamp(teUV, vec2(0.0), vec2(1.0));
        vec3 nts = dmUnpackUnormNormal(textureLod(baselineNormal, baselineUV(teFace, uv), 0.0).xyz);
        n = dmTangentSpaceDecode(nts, baselineTangent(teFace, uv, teSu, N), N);
    }
    // Two-sided Lambert with ambient.
    vec3 toEye = P.eye.xyz - teWorld;
    if (dot(n, toEye) < 0.0) {
        n = -n;
    }
    vec3 c = vec3(P.albedo.w);
    for (int i = 0; i < P.counts.x; ++i) {
        c += P.lights[i].color.rgb * max(dot(n, P.lights[i].direction.xyz), 0.0);
    }
    outColor = vec4(P.albedo.rgb * c, 1.0);
#ifndef DM_COLOR_ONLY
    outNormal = vec4(n, 1.0);
#endif
}

#version 450
// Tessellation factors (Nießner & Loop §6.1): a factor per base vertex by the scene's method,
// spread to the sub-patch corners by bilinear subdivision (an edge midpoint takes the mean of
// its edge's vertices, an N-gon centre the mean of the face's), halved on sub-faces of
// N-gons, clamped; edges take the larger corner, inner factors the larger opposite edge. Both
// faces of an edge compute its factor from the same vertices in the same order, so they agree
// bit for bit. T-junctions (a quad edge against two halves of an N-gon edge): the halves get
// an even integer h and the quad edge 2h, so the points of both sides coincide.
// Also the per-corner mip values of §6.2 / the texel-ratio rule for the evaluation shader.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
layout(vertices = 1) out;
layout(location = 0) flat in int vFace[];
layout(location = 0) patch out vec4 tcMip;   // per corner: mip factor (LOD 1) or resolution (LOD 2)
layout(location = 1) patch out int tcFace;

vec2 toPixels(vec3 p) {
    vec4 c = P.viewProj * vec4(p, 1.0);
    float w = max(c.w, 1e-6);
    return (c.xy / w * 0.5 + 0.5) * P.viewport.xy;
}

// The factor of base vertex b by the scene's method (before clamping).
float baseFactor(uint b) {
    BaseVertex v = baseVertices[b];
    if (TESS_METHOD == 1) {
        return dmTessFactorDistance(P.eye.xyz, v.position.xyz, P.tess.x);
    }
    if (TESS_METHOD == 2 || TESS_METHOD == 3) {
        vec2 p = toPixels(v.position.xyz);
        int n = v.ring.y;
        float longest = 0.0;
        float area = 0.0;
        vec2 first = vec2(0.0);
        vec2 prev = vec2(0.0);
        for (int i = 0; i < n; ++i) {
            vec2 e = toPixels(baseVertices[ringIndices[v.ring.x + i]].position.xyz) - p;
            longest = max(longest, length(e));
            if (i == 0) {
                first = e;
            } else {
                area += dmTessAreaTerm(prev, e);
            }
            prev = e;
        }
        if (v.ring.w != 0 && n > 2) {
            area += dmTessAreaTerm(prev, first);
        }
        return TESS_METHOD == 2 ? dmTessFactorEdge(longest, P.tess.x) : dmTessFactorArea(area, P.tess.x);
    }
    return P.tess.x;
}

// The mip value of base vertex b (Tessellator's per-vertex rule).
float baseMip(uint b, float F) {
    BaseVertex v = baseVertices[b];
    float f = min(F, P.tess.y);
    if (LOD == 1) {
        return max(f, exp2(v.position.w));
    }
    if (v.ring.z > 11) {
        return v.position.w;
    }
    return max(dmVertexResolutionTexelRatio(v.ring.z, max(f, 1.0)), v.position.w);
}

// Factor, mip value and largest base factor of a TileTopology vertex: means over its spread list
// (0.5 a + 0.5 b for two, a sum of x / n for more, as detail::spreadToTileVertices).
void tileVertex(uint tv, out float factor, out float mip, out float largest) {
    uvec2 s = tileVertices[tv];
    largest = 0.0;
    if (s.y == 1u) {
        uint b = spreadIndices[s.x];
        factor = baseFactor(b);
        largest = factor;
        mip = HAS_LOD ? baseMip(b, factor) : 0.0;
        return;
    }
    if (s.y == 2u) {
        uint a = spreadIndices[s.x];
        uint b = spreadIndices[s.x + 1u];
        float fa = baseFactor(a);
        float fb = baseFactor(b);
        factor = 0.5 * fa + 0.5 * fb;
        largest = max(fa, fb);
        mip = HAS_LOD ? 0.5 * baseMip(a, fa) + 0.5 * baseMip(b, fb) : 0.0;
        return;
    }
    float n = float(s.y);
    factor = 0.0;
    mip = 0.0;
    for (uint i = 0u; i < s.y; ++i) {
        uint b = spreadIndices[s.x + i];
        float f = baseFactor(b);
        factor += f / n;
        largest = max(largest, f);
        if (HAS_LOD) {
            mip += baseMip(b, f) / n;
        }
    }
}

void main() {
    int face = vFace[0];
    Face F = faces[face];
    float scale = F.info.x != 0 ? 0.5 : 1.0;
    vec4 corner;
    vec4 mips;
    vec4 largest;
    for (int c = 0; c < 4; ++c) {
        float f;
        float m;
        float l;
        tileVertex(F.corners[c], f, m, l);
        corner[c] = dmClampTessFactor(f * scale, P.tess.y);
        mips[c] = m;
        largest[c] = l;
    }
    vec4 edge = dmEdgeTessFactors(corner);
    for (int e = 0; e < 4; ++e) {
        if ((F.info.z & (1 << e)) != 0) {
            // The half edge of an N-gon: an even integer factor h from the base edge's larger
            // vertex factor; the quad across takes 2h.
            float big = max(largest[e], largest[(e + 1) & 3]);
            float h = 2.0 * ceil(0.5 * dmClampTessFactor(0.5 * big, 0.5 * P.tess.y));
            edge[e] = F.info.x != 0 ? h : 2.0 * h;
        }
    }
    vec2 inner = dmInnerTessFactors(edge);
    // Vulkan's quad domain: outer 0 is the edge u = 0, 1 is v = 0, 2 is u = 1, 3 is v = 1;
    // our edge i runs from corner i to i + 1 (0: v = 0, 1: u = 1, 2: v = 1, 3: u = 0).
    gl_TessLevelOuter[0] = edge.w;
    gl_TessLevelOuter[1] = edge.x;
    gl_TessLevelOuter[2] = edge.y;
    gl_TessLevelOuter[3] = edge.z;
    gl_TessLevelInner[0] = inner.x;
    gl_TessLevelInner[1] = inner.y;
    tcMip = mips;
    tcFace = face;
}

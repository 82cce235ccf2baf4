#version 330 core
// arenabench: the flat pass for a textured surface whose texture is sRGB (GL_SRGB8_ALPHA8).
// The sampler decodes texels to linear light before it filters them (bilinear within a mip
// level, linear between levels), as the competition's renderer (Gazebo Fortress, ogre2) does;
// the filtered colour is encoded back to sRGB here, then scaled by the material's factor (the
// uniform shading of the floor), so a uniform texture region comes out exactly as it is.
// Used in place of pyrender's flat.frag for textured primitives (pyrender_compat.py).

struct Material {
    vec3 emissive_factor;
    vec4 base_color_factor;
    float metallic_factor;
    float roughness_factor;
    sampler2D base_color_texture;
};

uniform Material material;

in vec3 frag_position;
in vec2 uv_0;
#ifdef COLOR_0_LOC
in vec4 color_multiplier;
#endif

out vec4 frag_color;

vec3 linear_to_srgb(vec3 c)
{
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main()
{
    // GL's level of detail, lambda = log2(rho), rho the larger of the texel footprints of a
    // pixel step in x and in y (derivatives per 2 x 2 quad, as GPUs take them), computed
    // exactly: llvmpipe's implicit lambda comes out 0.03-0.04 lower (docs/rendering.md)
    vec2 texels = uv_0 * vec2(textureSize(material.base_color_texture, 0));
    float rho = max(length(dFdx(texels)), length(dFdy(texels)));
    vec4 texel = textureLod(material.base_color_texture, uv_0, log2(rho));
    vec4 base_color = material.base_color_factor * vec4(linear_to_srgb(texel.rgb), texel.a);
#ifdef COLOR_0_LOC
    base_color *= color_multiplier;
#endif
    frag_color = clamp(base_color, 0.0, 1.0);
}

#include "gpu/render/cluster_preview.h"

#include <EGL/egl.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/status_macros.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/render/render_gl_functions.h"

namespace mlclust::gpu {

namespace detail {

absl::StatusOr<RenderGlFunctions> LoadRenderGlFunctions() {
  RenderGlFunctions gl;
  std::vector<std::string> missing;
#define MLCLUST_GPU_LOAD_RENDER_GL_FUNCTION(suffix, name)                       \
  gl.name = reinterpret_cast<PFN##suffix##PROC>(eglGetProcAddress("gl" #name)); \
  if (gl.name == nullptr) missing.push_back("gl" #name);
  MLCLUST_GPU_RENDER_GL_FUNCTION_LIST(MLCLUST_GPU_LOAD_RENDER_GL_FUNCTION)
#undef MLCLUST_GPU_LOAD_RENDER_GL_FUNCTION
  if (!missing.empty()) {
    return absl::UnavailableError(
        absl::StrCat("preview: eglGetProcAddress found no ", absl::StrJoin(missing, ", ")));
  }
  return gl;
}

}  // namespace detail

namespace {

// The shaders draw without vertex attributes ("vertex pulling"): vertex 3f + c of a draw is
// corner c of face f, read from the storage buffers, so each corner gets its own
// barycentric coordinate (for the border lines) and each face its flat normal, from one
// indexed mesh and no duplicated vertex data.
constexpr char kVertexShader[] = R"glsl(#version 450 core
layout(std430, binding = 0) readonly buffer Positions { float positions[]; };
layout(std430, binding = 1) readonly buffer Indices { uint indices[]; };
layout(location = 0) uniform mat4 view_projection;
layout(location = 1) uniform mat4 view_rotation;
flat out uint face;
flat out vec3 normal_view;
noperspective out vec3 barycentric;

vec3 Corner(uint f, uint c) {
  uint v = indices[3u * f + c];
  return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

void main() {
  uint f = uint(gl_VertexID) / 3u;
  uint c = uint(gl_VertexID) % 3u;
  vec3 p0 = Corner(f, 0u), p1 = Corner(f, 1u), p2 = Corner(f, 2u);
  vec3 p = c == 0u ? p0 : (c == 1u ? p1 : p2);
  normal_view = mat3(view_rotation) * cross(p1 - p0, p2 - p0);
  barycentric = vec3(c == 0u ? 1.0 : 0.0, c == 1u ? 1.0 : 0.0, c == 2u ? 1.0 : 0.0);
  face = f;
  gl_Position = view_projection * vec4(p, 1.0);
}
)glsl";

// Border edge e runs from corner e to corner e + 1, so the opposite corner is e + 2 and
// the distance to the edge in pixels is that corner's barycentric coordinate over its
// screen-space derivative. The step is hard (no blending), so every pixel is either a
// face's shaded colour or the border grey.
constexpr char kFragmentShader[] = R"glsl(#version 450 core
layout(std430, binding = 2) readonly buffer FaceColours { uint face_colour[]; };
layout(location = 2) uniform vec3 light_view;
layout(location = 3) uniform float border_half_width;
layout(location = 4) uniform vec3 border_colour;
flat in uint face;
flat in vec3 normal_view;
noperspective in vec3 barycentric;
layout(location = 0) out vec4 colour;

void main() {
  uint face_word = face_colour[face];
  vec3 base = vec3(float(face_word & 255u), float((face_word >> 8) & 255u),
                   float((face_word >> 16) & 255u)) / 255.0;
  uint borders = face_word >> 24;
  vec3 pixels = barycentric / max(fwidth(barycentric), vec3(1e-7));
  bool on_border = ((borders & 1u) != 0u && pixels.z < border_half_width) ||
                   ((borders & 2u) != 0u && pixels.x < border_half_width) ||
                   ((borders & 4u) != 0u && pixels.y < border_half_width);
  float length_n = length(normal_view);
  float lambert = length_n > 0.0 ? abs(dot(normal_view / length_n, light_view)) : 1.0;
  float shade = 0.35 + 0.65 * lambert;
  colour = on_border ? vec4(border_colour, 1.0) : vec4(base * shade, 1.0);
}
)glsl";

constexpr char kProgramName[] = "render/cluster_preview";

// The hue sequence i * (golden ratio - 1) turns spreads any prefix evenly around the
// circle; saturation and value follow two other low-discrepancy sequences so that hues
// that come close again differ in those.
std::array<uint8_t, 3> PaletteColour(uint32_t i) {
  const double hue = std::fmod(0.08 + i * 0.6180339887498949, 1.0);
  const double saturation = 0.55 + 0.3 * std::fmod(i * 0.7548776662466927, 1.0);
  const double value = 0.82 + 0.16 * std::fmod(i * 0.5698402909980532, 1.0);
  const double h6 = hue * 6.0;
  const int sector = static_cast<int>(h6) % 6;
  const double fraction = h6 - std::floor(h6);
  const double p = value * (1 - saturation);
  const double q = value * (1 - saturation * fraction);
  const double t = value * (1 - saturation * (1 - fraction));
  // HSV to RGB: per sector, (r, g, b) as indices into {value, p, q, t}.
  static constexpr int kSectorChannels[6][3] = {{0, 3, 1}, {2, 0, 1}, {1, 0, 3},
                                                {1, 2, 0}, {3, 1, 0}, {0, 1, 2}};
  const double channel[4] = {value, p, q, t};
  const int* rgb = kSectorChannels[sector];
  const auto byte = [](double x) { return static_cast<uint8_t>(std::lround(x * 255.0)); };
  return {byte(channel[rgb[0]]), byte(channel[rgb[1]]), byte(channel[rgb[2]])};
}

double SquaredColourDistance(const std::array<uint8_t, 3>& a, const std::array<uint8_t, 3>& b) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = static_cast<double>(a[i]) - b[i];
    sum += d * d;
  }
  return sum;
}

uint32_t Pack(const std::array<uint8_t, 3>& colour) {
  return uint32_t{colour[0]} | (uint32_t{colour[1]} << 8) | (uint32_t{colour[2]} << 16);
}

// A 4 x 4 matrix, row-major (uploaded with transpose = GL_TRUE).
using Matrix4 = std::array<float, 16>;

struct Camera {
  Matrix4 view_projection{};
  Matrix4 view_rotation{};
};

// The three-quarter view of the header, fitted to the vertices the faces use.
Camera FitCamera(const TriangleMesh& mesh, const ClusterPreviewOptions& options) {
  constexpr double kPi = 3.14159265358979323846;
  const double azimuth = options.azimuth_degrees * kPi / 180.0;
  const double elevation = options.elevation_degrees * kPi / 180.0;
  const uint32_t width = options.width, height = options.height;
  // View axes: z towards the camera, x to its right, y up.
  const double z[3] = {std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                       std::cos(azimuth) * std::cos(elevation)};
  // x = normalize(up x z) with up = +y.
  double x[3] = {z[2], 0.0, -z[0]};
  const double x_length = std::hypot(x[0], x[2]);
  x[0] /= x_length;
  x[2] /= x_length;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2],
                       z[0] * x[1] - z[1] * x[0]};
  double low[3] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
                   std::numeric_limits<double>::max()};
  double high[3] = {std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest(),
                    std::numeric_limits<double>::lowest()};
  const double* axes[3] = {x, y, z};
  for (uint32_t vertex : mesh.indices) {
    const float* p = &mesh.positions[3 * static_cast<size_t>(vertex)];
    for (int a = 0; a < 3; ++a) {
      const double v = axes[a][0] * p[0] + axes[a][1] * p[1] + axes[a][2] * p[2];
      low[a] = std::min(low[a], v);
      high[a] = std::max(high[a], v);
    }
  }
  double centre[3], half[3];
  for (int a = 0; a < 3; ++a) {
    centre[a] = 0.5 * (low[a] + high[a]);
    half[a] = 0.5 * (high[a] - low[a]);
  }
  // 6% margin around the picture; depth a little wider so nothing touches the clip planes.
  double extent = std::max({half[0], half[1], half[2]});
  if (!(extent > 1e-20)) {
    // Every vertex at one point (zero-area faces): any finite box shows it.
    extent = 1.0;
    half[0] = half[1] = half[2] = 1.0;
  }
  double half_x = std::max(half[0], 1e-6 * extent) * 1.06;
  double half_y = std::max(half[1], 1e-6 * extent) * 1.06;
  const double half_z = std::max(half[2], 1e-6 * extent) * 1.02;
  const double aspect = static_cast<double>(width) / height;
  if (half_x / half_y < aspect) {
    half_x = half_y * aspect;
  } else {
    half_y = half_x / aspect;
  }
  // NDC = ((v.x - cx) / hx, (v.y - cy) / hy, -(v.z - cz) / hz): nearer is smaller depth.
  const double scale[3] = {1.0 / half_x, 1.0 / half_y, -1.0 / half_z};
  Camera camera;
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      camera.view_projection[4 * row + column] = static_cast<float>(scale[row] * axes[row][column]);
      camera.view_rotation[4 * row + column] = static_cast<float>(axes[row][column]);
    }
    camera.view_projection[4 * row + 3] = static_cast<float>(-scale[row] * centre[row]);
  }
  camera.view_projection[15] = 1.0f;
  camera.view_rotation[15] = 1.0f;
  return camera;
}

absl::StatusOr<GLuint> CompileStage(const detail::GlFunctions& gl, GLenum stage, const char* source,
                                    const char* what) {
  const GLuint shader = gl.CreateShader(stage);
  if (shader == 0) return absl::InternalError(absl::StrCat("preview: glCreateShader(", what, ")"));
  MLCLUST_RETURN_IF_ERROR(CompileShaderSource(gl, shader, source, absl::StrCat("preview: ", what)));
  return shader;
}

// The drawing program, compiled once per context and kept in its program cache.
absl::StatusOr<GLuint> PreviewProgram(GlContext& context) {
  auto& cache = context.program_cache();
  if (auto it = cache.find(kProgramName); it != cache.end()) return it->second;
  const detail::GlFunctions& gl = context.gl();
  MLCLUST_ASSIGN_OR_RETURN(const GLuint vertex,
                           CompileStage(gl, GL_VERTEX_SHADER, kVertexShader, "vertex"));
  absl::StatusOr<GLuint> fragment =
      CompileStage(gl, GL_FRAGMENT_SHADER, kFragmentShader, "fragment");
  if (!fragment.ok()) {
    gl.DeleteShader(vertex);
    return fragment.status();
  }
  const GLuint program = gl.CreateProgram();
  gl.AttachShader(program, vertex);
  gl.AttachShader(program, *fragment);
  gl.LinkProgram(program);
  gl.DetachShader(program, vertex);
  gl.DetachShader(program, *fragment);
  gl.DeleteShader(vertex);
  gl.DeleteShader(*fragment);
  MLCLUST_RETURN_IF_ERROR(CheckProgramLinked(gl, program, "preview: the program"));
  cache.emplace(kProgramName, program);
  return program;
}

// The framebuffer, its two renderbuffers and the empty vertex array of one render,
// deleted (and the default state restored) on every path out.
class RenderTarget {
 public:
  RenderTarget(const detail::RenderGlFunctions& gl, const detail::GlFunctions& base)
      : gl_(gl), base_(base) {}
  RenderTarget(const RenderTarget&) = delete;
  RenderTarget& operator=(const RenderTarget&) = delete;
  ~RenderTarget() {
    gl_.BindFramebuffer(GL_FRAMEBUFFER, 0);
    gl_.BindVertexArray(0);
    base_.UseProgram(0);
    if (framebuffer != 0) gl_.DeleteFramebuffers(1, &framebuffer);
    if (renderbuffers[0] != 0) gl_.DeleteRenderbuffers(2, renderbuffers);
    if (vertex_array != 0) gl_.DeleteVertexArrays(1, &vertex_array);
    gl_.Disable(GL_DEPTH_TEST);
  }

  GLuint framebuffer = 0;
  GLuint renderbuffers[2] = {0, 0};  // colour, depth
  GLuint vertex_array = 0;

 private:
  const detail::RenderGlFunctions& gl_;
  const detail::GlFunctions& base_;
};

}  // namespace

absl::StatusOr<ClusterPreviewColours> ColourClusters(const FaceAdjacency& adjacency,
                                                     std::span<const ClusterId> labels) {
  const size_t faces = adjacency.num_faces();
  if (labels.size() != faces) {
    return absl::InvalidArgumentError(
        absl::StrCat("preview: ", labels.size(), " labels for a mesh of ", faces, " faces"));
  }
  // Clusters numbered in order of their first face.
  absl::flat_hash_map<uint32_t, uint32_t> index;
  std::vector<uint32_t> cluster(faces, ClusterId::kInvalidValue);
  for (size_t f = 0; f < faces; ++f) {
    if (!labels[f].valid()) continue;
    cluster[f] =
        index.try_emplace(labels[f].value(), static_cast<uint32_t>(index.size())).first->second;
  }
  const uint32_t k = static_cast<uint32_t>(index.size());
  // Cluster adjacency in compressed rows, from the faces' pairs across cluster borders.
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (size_t f = 0; f < faces; ++f) {
    for (FaceId g : adjacency.neighbours[f]) {
      if (!g.valid() || cluster[f] == ClusterId::kInvalidValue) continue;
      const uint32_t other = cluster[g.value()];
      if (other != ClusterId::kInvalidValue && other != cluster[f]) {
        pairs.emplace_back(cluster[f], other);
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<uint32_t> offset(k + 1, 0);
  for (const auto& [a, b] : pairs) ++offset[a + 1];
  for (uint32_t c = 0; c < k; ++c) offset[c + 1] += offset[c];

  // Greedy: each cluster takes the pool entry farthest from its coloured neighbours.
  constexpr uint32_t kPool = 8;
  ClusterPreviewColours out;
  out.cluster_count = k;
  out.cluster_colour.resize(k);
  std::vector<char> coloured(k, 0);
  std::vector<uint32_t> pool;
  uint32_t next_entry = 0;
  for (uint32_t c = 0; c < k; ++c) {
    while (pool.size() < kPool) pool.push_back(next_entry++);
    size_t best = 0;
    double best_distance = -1;
    for (size_t j = 0; j < pool.size(); ++j) {
      const std::array<uint8_t, 3> candidate = PaletteColour(pool[j]);
      double nearest = std::numeric_limits<double>::max();
      for (uint32_t e = offset[c]; e < offset[c + 1]; ++e) {
        const uint32_t neighbour = pairs[e].second;
        if (coloured[neighbour]) {
          nearest =
              std::min(nearest, SquaredColourDistance(candidate, out.cluster_colour[neighbour]));
        }
      }
      if (nearest > best_distance) {
        best_distance = nearest;
        best = j;
      }
    }
    out.cluster_colour[c] = PaletteColour(pool[best]);
    coloured[c] = 1;
    pool.erase(pool.begin() + static_cast<std::ptrdiff_t>(best));
  }

  out.face.resize(faces);
  for (size_t f = 0; f < faces; ++f) {
    if (cluster[f] == ClusterId::kInvalidValue) {
      out.face[f] = Pack(kPreviewNoCluster);
      continue;
    }
    uint32_t packed = Pack(out.cluster_colour[cluster[f]]);
    for (int e = 0; e < 3; ++e) {
      const FaceId g = adjacency.neighbours[f][e];
      if (g.valid() && cluster[g.value()] != cluster[f]) packed |= uint32_t{1} << (24 + e);
    }
    out.face[f] = packed;
  }
  return out;
}

absl::StatusOr<RgbaImage> RenderClusterPreview(GlContext& context, const TriangleMesh& mesh,
                                               const FaceAdjacency& adjacency,
                                               std::span<const ClusterId> labels,
                                               const ClusterPreviewOptions& options) {
  const size_t faces = mesh.num_faces();
  if (adjacency.num_faces() != faces) {
    return absl::InvalidArgumentError(absl::StrCat("preview: adjacency of ", adjacency.num_faces(),
                                                   " faces for a mesh of ", faces));
  }
  if (faces == 0) return absl::InvalidArgumentError("preview: the mesh has no faces");
  if (!std::isfinite(options.azimuth_degrees) || !(options.elevation_degrees >= -89.0f) ||
      !(options.elevation_degrees <= 89.0f)) {
    return absl::InvalidArgumentError(absl::StrCat("preview: azimuth ", options.azimuth_degrees,
                                                   ", elevation ", options.elevation_degrees,
                                                   " degrees (the elevation in [-89, 89])"));
  }
  if (!(options.border_half_width_pixels >= 0.0f)) {
    return absl::InvalidArgumentError("preview: border_half_width_pixels must be >= 0");
  }
  MLCLUST_RETURN_IF_ERROR(context.MakeCurrent());
  const detail::GlFunctions& base = context.gl();
  MLCLUST_ASSIGN_OR_RETURN(const detail::RenderGlFunctions gl, detail::LoadRenderGlFunctions());

  GLint max_renderbuffer = 0;
  GLint max_viewport[2] = {0, 0};
  GLint vertex_storage_blocks = 0;
  base.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_renderbuffer);
  base.GetIntegerv(GL_MAX_VIEWPORT_DIMS, max_viewport);
  base.GetIntegerv(GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS, &vertex_storage_blocks);
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "preview: reading the limits"));
  const int64_t max_width = std::min<int64_t>(max_renderbuffer, max_viewport[0]);
  const int64_t max_height = std::min<int64_t>(max_renderbuffer, max_viewport[1]);
  if (options.width == 0 || options.height == 0 || options.width > max_width ||
      options.height > max_height) {
    return absl::InvalidArgumentError(
        absl::StrCat("preview: ", options.width, " x ", options.height, " pixels; this GL (",
                     context.renderer(), ") draws 1 x 1 to ", max_width, " x ", max_height));
  }
  if (vertex_storage_blocks < 2) {
    return absl::UnavailableError(
        absl::StrCat("preview: ", context.renderer(), " has ", vertex_storage_blocks,
                     " storage buffers in the vertex stage; drawing the mesh needs 2"));
  }
  MLCLUST_ASSIGN_OR_RETURN(ClusterPreviewColours colours, ColourClusters(adjacency, labels));
  MLCLUST_ASSIGN_OR_RETURN(const GLuint program, PreviewProgram(context));

  // Vertices: one buffer; faces: chunks of what one buffer holds (12 bytes each for the
  // indices, the larger of the two per-face arrays).
  const uint64_t position_bytes = mesh.positions.size() * sizeof(float);
  if (position_bytes > static_cast<uint64_t>(context.max_storage_buffer_bytes())) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "preview: ", mesh.num_vertices(), " vertices (", position_bytes,
        " bytes) do not fit one storage buffer of ", context.max_storage_buffer_bytes(), " bytes"));
  }
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer positions, StorageBuffer::Create(context, position_bytes));
  MLCLUST_RETURN_IF_ERROR(positions.Upload(std::span<const float>(mesh.positions)));
  const uint64_t chunk_faces = std::min<uint64_t>(
      {faces, MaxElementsPerBuffer(context, 3 * sizeof(uint32_t)), kMaxElementsPerChunk});
  if (chunk_faces == 0) return absl::ResourceExhaustedError("preview: no face fits a buffer");
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer indices,
                           StorageBuffer::Create(context, chunk_faces * 3 * sizeof(uint32_t)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer face_colours,
                           StorageBuffer::Create(context, chunk_faces * sizeof(uint32_t)));

  RenderTarget target(gl, base);
  gl.CreateRenderbuffers(2, target.renderbuffers);
  gl.NamedRenderbufferStorage(target.renderbuffers[0], GL_RGBA8,
                              static_cast<GLsizei>(options.width),
                              static_cast<GLsizei>(options.height));
  gl.NamedRenderbufferStorage(target.renderbuffers[1], GL_DEPTH_COMPONENT32F,
                              static_cast<GLsizei>(options.width),
                              static_cast<GLsizei>(options.height));
  gl.CreateFramebuffers(1, &target.framebuffer);
  gl.NamedFramebufferRenderbuffer(target.framebuffer, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                  target.renderbuffers[0]);
  gl.NamedFramebufferRenderbuffer(target.framebuffer, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                                  target.renderbuffers[1]);
  gl.NamedFramebufferDrawBuffer(target.framebuffer, GL_COLOR_ATTACHMENT0);
  gl.NamedFramebufferReadBuffer(target.framebuffer, GL_COLOR_ATTACHMENT0);
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "preview: creating the framebuffer"));
  const GLenum complete = gl.CheckNamedFramebufferStatus(target.framebuffer, GL_FRAMEBUFFER);
  if (complete != GL_FRAMEBUFFER_COMPLETE) {
    return absl::InternalError(absl::StrCat("preview: the framebuffer is incomplete (status 0x",
                                            absl::Hex(complete), ")"));
  }
  gl.CreateVertexArrays(1, &target.vertex_array);

  const Camera camera = FitCamera(mesh, options);
  // A light from the upper left, in front of the camera (view space).
  const float light[3] = {-0.35f, 0.55f, 1.0f};
  const float light_length = std::sqrt(light[0] * light[0] + light[1] * light[1] + 1.0f);
  gl.ProgramUniformMatrix4fv(program, 0, 1, GL_TRUE, camera.view_projection.data());
  gl.ProgramUniformMatrix4fv(program, 1, 1, GL_TRUE, camera.view_rotation.data());
  gl.ProgramUniform3f(program, 2, light[0] / light_length, light[1] / light_length,
                      light[2] / light_length);
  gl.ProgramUniform1f(program, 3, options.border_half_width_pixels);
  gl.ProgramUniform3f(program, 4, kPreviewBorder[0] / 255.0f, kPreviewBorder[1] / 255.0f,
                      kPreviewBorder[2] / 255.0f);

  gl.BindFramebuffer(GL_FRAMEBUFFER, target.framebuffer);
  gl.Viewport(0, 0, static_cast<GLsizei>(options.width), static_cast<GLsizei>(options.height));
  gl.Disable(GL_BLEND);
  gl.Disable(GL_CULL_FACE);
  gl.Disable(GL_SCISSOR_TEST);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_LESS);
  gl.DepthMask(GL_TRUE);
  gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl.ClearColor(kPreviewBackground[0] / 255.0f, kPreviewBackground[1] / 255.0f,
                kPreviewBackground[2] / 255.0f, 1.0f);
  gl.ClearDepth(1.0);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.BindVertexArray(target.vertex_array);
  base.UseProgram(program);
  positions.Bind(0);
  indices.Bind(1);
  face_colours.Bind(2);
  for (uint64_t first = 0; first < faces; first += chunk_faces) {
    const uint64_t count = std::min<uint64_t>(chunk_faces, faces - first);
    MLCLUST_RETURN_IF_ERROR(
        indices.Upload(std::span<const uint32_t>(mesh.indices.data() + 3 * first, 3 * count)));
    MLCLUST_RETURN_IF_ERROR(
        face_colours.Upload(std::span<const uint32_t>(colours.face.data() + first, count)));
    gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(3 * count));
    // The next chunk's uploads overwrite the buffers this draw reads. GL says an update
    // waits for earlier draws, but llvmpipe let it reach a draw still rasterising (the
    // chunked test saw 7,206 bytes differ), so wait; only meshes too large for one
    // buffer pay for it.
    if (first + count < faces) base.Finish();
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "preview: drawing the faces"));
  }

  RgbaImage image;
  image.width = options.width;
  image.height = options.height;
  const size_t row_bytes = 4 * static_cast<size_t>(options.width);
  std::vector<uint8_t> bottom_up(row_bytes * options.height);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, static_cast<GLsizei>(options.width), static_cast<GLsizei>(options.height),
                GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data());
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, "preview: reading the pixels back"));
  image.rgba.resize(bottom_up.size());
  for (uint32_t row = 0; row < options.height; ++row) {
    std::copy_n(bottom_up.data() + (options.height - 1 - row) * row_bytes, row_bytes,
                image.rgba.data() + static_cast<size_t>(row) * row_bytes);
  }
  return image;
}

}  // namespace mlclust::gpu

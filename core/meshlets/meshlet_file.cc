#include "core/meshlets/meshlet_file.h"

#include <bit>
#include <cstring>
#include <fstream>
#include <limits>

#include "absl/strings/str_cat.h"

namespace mlclust {
namespace {

constexpr uint32_t kBoundsFlag = 1;
constexpr size_t kBoundsBytes = 48;
constexpr size_t kMeshletBytes = 16;
static_assert(sizeof(Meshlet) == kMeshletBytes);

// Little-endian writes and reads (the host order of every platform we build for is checked
// once here, so the arrays can be copied as they are).
static_assert(std::endian::native == std::endian::little, "meshlet files are little-endian");

void PutU32(std::string& out, uint32_t value) {
  char bytes[4];
  std::memcpy(bytes, &value, 4);
  out.append(bytes, 4);
}

uint32_t GetU32(const std::string& bytes, size_t offset) {
  uint32_t value = 0;
  std::memcpy(&value, bytes.data() + offset, 4);
  return value;
}

template <typename T>
void PutArray(std::string& out, const std::vector<T>& values) {
  out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

}  // namespace

std::string EncodeMeshletBounds(const std::vector<MeshletBounds>& bounds) {
  std::string out;
  out.reserve(kBoundsBytes * bounds.size());
  for (const MeshletBounds& b : bounds) {
    const float floats[11] = {b.center[0],    b.center[1],    b.center[2],    b.radius,
                              b.cone_apex[0], b.cone_apex[1], b.cone_apex[2], b.cone_axis[0],
                              b.cone_axis[1], b.cone_axis[2], b.cone_cutoff};
    out.append(reinterpret_cast<const char*>(floats), sizeof(floats));
    const int8_t snorm[4] = {b.cone_axis_s8[0], b.cone_axis_s8[1], b.cone_axis_s8[2],
                             b.cone_cutoff_s8};
    out.append(reinterpret_cast<const char*>(snorm), sizeof(snorm));
  }
  return out;
}

absl::StatusOr<std::string> EncodeMeshletFile(const MeshletResult& meshlets, uint32_t vertex_count,
                                              uint32_t max_vertices, uint32_t max_triangles) {
  constexpr size_t kMax = std::numeric_limits<uint32_t>::max();
  if (meshlets.meshlets.size() > kMax || meshlets.meshlet_vertices.size() > kMax ||
      meshlets.meshlet_triangles.size() > kMax || meshlets.triangle_faces.size() > kMax) {
    return absl::InvalidArgumentError("meshlet file: an array longer than 32 bits can count");
  }
  const bool bounds = !meshlets.bounds.empty();
  std::string out;
  out.reserve(kMeshletFileHeaderBytes + kMeshletBytes * meshlets.meshlets.size() +
              4 * meshlets.meshlet_vertices.size() + meshlets.meshlet_triangles.size() +
              4 * meshlets.triangle_faces.size() + kBoundsBytes * meshlets.bounds.size());
  out.append(kMeshletFileMagic, sizeof(kMeshletFileMagic));
  PutU32(out, kMeshletFileVersion);
  PutU32(out, kMeshletFileHeaderBytes);
  PutU32(out, max_vertices);
  PutU32(out, max_triangles);
  PutU32(out, static_cast<uint32_t>(meshlets.meshlets.size()));
  PutU32(out, static_cast<uint32_t>(meshlets.meshlet_vertices.size()));
  PutU32(out, static_cast<uint32_t>(meshlets.meshlet_triangles.size()));
  PutU32(out, static_cast<uint32_t>(meshlets.triangle_faces.size()));
  PutU32(out, vertex_count);
  PutU32(out, bounds ? kBoundsFlag : 0);
  out.resize(kMeshletFileHeaderBytes, '\0');
  PutArray(out, meshlets.meshlets);
  PutArray(out, meshlets.meshlet_vertices);
  PutArray(out, meshlets.meshlet_triangles);
  PutArray(out, meshlets.triangle_faces);
  out += EncodeMeshletBounds(meshlets.bounds);
  return out;
}

absl::StatusOr<MeshletFile> DecodeMeshletFile(const std::string& bytes) {
  auto fail = [](absl::string_view what) {
    return absl::InvalidArgumentError(absl::StrCat("meshlet file: ", what));
  };
  if (bytes.size() < kMeshletFileHeaderBytes) {
    return fail(absl::StrCat(bytes.size(), " bytes, shorter than the 64-byte header"));
  }
  if (std::memcmp(bytes.data(), kMeshletFileMagic, sizeof(kMeshletFileMagic)) != 0) {
    return fail("no MLCMSHLT magic at byte 0");
  }
  if (const uint32_t version = GetU32(bytes, 8); version != kMeshletFileVersion) {
    return fail(absl::StrCat("version ", version, "; this reader knows ", kMeshletFileVersion));
  }
  if (const uint32_t header = GetU32(bytes, 12); header != kMeshletFileHeaderBytes) {
    return fail(absl::StrCat("header of ", header, " bytes; version 1 has 64"));
  }
  MeshletFile file;
  file.max_vertices = GetU32(bytes, 16);
  file.max_triangles = GetU32(bytes, 20);
  const uint64_t meshlet_count = GetU32(bytes, 24);
  const uint64_t vertex_entries = GetU32(bytes, 28);
  const uint64_t triangle_bytes = GetU32(bytes, 32);
  const uint64_t face_count = GetU32(bytes, 36);
  file.vertex_count = GetU32(bytes, 40);
  const uint32_t flags = GetU32(bytes, 44);
  if ((flags & ~kBoundsFlag) != 0) return fail(absl::StrCat("unknown flags ", flags));
  for (size_t i = 48; i < kMeshletFileHeaderBytes; ++i) {
    if (bytes[i] != 0) return fail(absl::StrCat("header byte ", i, " is not zero"));
  }
  if (triangle_bytes % 4 != 0) {
    return fail(absl::StrCat("triangle bytes ", triangle_bytes, " not a multiple of 4"));
  }
  const bool bounds = (flags & kBoundsFlag) != 0;
  const uint64_t expected = kMeshletFileHeaderBytes + kMeshletBytes * meshlet_count +
                            4 * vertex_entries + triangle_bytes + 4 * face_count +
                            (bounds ? kBoundsBytes * meshlet_count : 0);
  if (expected != bytes.size()) {
    return fail(absl::StrCat(bytes.size(), " bytes where the header's counts make ", expected));
  }
  MeshletResult& result = file.meshlets;
  size_t at = kMeshletFileHeaderBytes;
  auto take = [&](auto& values, uint64_t count) {
    values.resize(count);
    std::memcpy(values.data(), bytes.data() + at, count * sizeof(values[0]));
    at += count * sizeof(values[0]);
  };
  take(result.meshlets, meshlet_count);
  take(result.meshlet_vertices, vertex_entries);
  take(result.meshlet_triangles, triangle_bytes);
  take(result.triangle_faces, face_count);
  if (bounds) {
    result.bounds.resize(meshlet_count);
    for (MeshletBounds& b : result.bounds) {
      float floats[11];
      std::memcpy(floats, bytes.data() + at, sizeof(floats));
      int8_t snorm[4];
      std::memcpy(snorm, bytes.data() + at + sizeof(floats), sizeof(snorm));
      at += kBoundsBytes;
      std::memcpy(b.center, floats, 3 * sizeof(float));
      b.radius = floats[3];
      std::memcpy(b.cone_apex, floats + 4, 3 * sizeof(float));
      std::memcpy(b.cone_axis, floats + 7, 3 * sizeof(float));
      b.cone_cutoff = floats[10];
      std::memcpy(b.cone_axis_s8, snorm, 3);
      b.cone_cutoff_s8 = snorm[3];
    }
  }
  for (size_t i = 0; i < result.meshlet_vertices.size(); ++i) {
    if (result.meshlet_vertices[i] >= file.vertex_count) {
      return fail(absl::StrCat("meshlet vertex entry ", i, " is vertex ",
                               result.meshlet_vertices[i], " of ", file.vertex_count));
    }
  }
  // face_meshlet from triangle_faces; a face out of range or twice is left to the check.
  result.face_meshlet.assign(face_count, std::numeric_limits<uint32_t>::max());
  size_t triangle = 0;
  for (size_t m = 0; m < result.meshlets.size(); ++m) {
    for (uint32_t t = 0; t < result.meshlets[m].triangle_count && triangle < face_count;
         ++t, ++triangle) {
      const uint32_t face = result.triangle_faces[triangle];
      if (face < face_count) result.face_meshlet[face] = static_cast<uint32_t>(m);
    }
  }
  absl::Status layout = CheckMeshletLayout(result, file.max_vertices, file.max_triangles);
  if (!layout.ok()) return fail(layout.message());
  // The padding after each meshlet's triangles is zero (as meshoptimizer writes it).
  for (size_t m = 0; m < result.meshlets.size(); ++m) {
    const Meshlet& meshlet = result.meshlets[m];
    const size_t end = meshlet.triangle_offset + ((3 * size_t{meshlet.triangle_count} + 3) & ~3u);
    for (size_t i = meshlet.triangle_offset + 3 * size_t{meshlet.triangle_count}; i < end; ++i) {
      if (result.meshlet_triangles[i] != 0) {
        return fail(absl::StrCat("meshlet ", m, ": padding byte ", i, " is not zero"));
      }
    }
  }
  return file;
}

absl::Status WriteMeshletFile(const std::string& path, const MeshletResult& meshlets,
                              uint32_t vertex_count, uint32_t max_vertices,
                              uint32_t max_triangles) {
  absl::StatusOr<std::string> bytes =
      EncodeMeshletFile(meshlets, vertex_count, max_vertices, max_triangles);
  if (!bytes.ok()) return bytes.status();
  std::ofstream out(path, std::ios::binary);
  out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write the meshlet file ", path));
  return absl::OkStatus();
}

}  // namespace mlclust

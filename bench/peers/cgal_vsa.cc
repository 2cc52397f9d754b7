// cgal_vsa: CGAL's Variational Shape Approximation (Cohen-Steiner, Alliez, Desbrun 2004) as
// a benchmark peer for mlclust. Times CGAL's seeding and its Lloyd iterations on a triangle
// mesh, and measures the result with the L2,1 energy computed the same way for every
// program we compare, from the final face -> proxy labels alone:
//
//   E = sum_i sum_{j in C_i} A_j ||n_j - N_i||^2
//
// with A_j the face's area, n_j its unit normal (zero for a face of zero area) and N_i the
// normalised area-weighted mean normal of cluster i (zero if that sum is zero).
//
//   cgal_vsa MESH.off --k K [--seeding random|incremental|hierarchical] [--iterations N]
//            [--relaxations R] [--metric l21|l2] [--labels OUT] [--seed S] [--repeats R]
//            [--header]
//
// What CGAL is asked to do (CGAL 5.5, Variational_shape_approximation.h), per repeat:
//
//   std::srand(S);                                   // CGAL's random seeding uses std::rand
//   Metric metric(mesh, get(boost::vertex_point, mesh));          // L21 or L2 plane proxy
//   CGAL::Variational_shape_approximation<Mesh, Vpm, Metric> vsa(mesh, vpm, metric);
//   vsa.initialize_seeds(CGAL::parameters::seeding_method(METHOD)
//                            .max_number_of_proxies(K)
//                            .number_of_relaxations(5));             // CGAL's default
//   vsa.run(N);                                                       // N = 30 by default
//
// Seeding. With max_number_of_proxies = K < faces / 3 and no min_error_drop, CGAL seeds
// exactly up to K proxies (min_error_drop is set to -1, i.e. ignored): it first puts one
// proxy on each connected component; RANDOM then adds the missing seeds at random faces at
// once and relaxes 5 times; INCREMENTAL adds one proxy at a time at the worst face of the
// worst proxy, relaxing 5 times after each (K runs of 5 iterations: slow for large K);
// HIERARCHICAL doubles the number of proxies per round, spreading the new ones over regions
// in proportion to their error, and relaxes 5 times per round. If K >= faces / 3, CGAL
// replaces K by faces / 3 and stops at an error drop of 0.1: "k obtained" then differs.
//
// Iterations. N = 30 by default, as in CGAL's class-interface example
// (vsa_class_interface_example.cpp: initialize_seeds(RANDOM, 100 proxies), then run(30)).
// The free function approximate_triangle_mesh documents
// min(max(faces / K, 20), 60) iterations as its default but, in 5.5.1, uses 20.
// Each iteration is one flooding partition (a priority queue over all faces) and one
// refit of every proxy.
//
// Face order. The mesh is read by our own OFF reader and built with Surface_mesh::add_vertex
// and add_face in file order, so face index i is the file's face i (checked: add_face must
// return index i, and afterwards every face's vertex cycle must equal the file's triangle
// up to rotation). Labels written with --labels are therefore in the input face order,
// the order mlclust uses for its own labels. (CGAL's own reader, CGAL::IO::read_OFF into a
// Surface_mesh, keeps the file's face and vertex order too on fandisk, bunny00, armadillo,
// elephant and fandisk_large, checked once face by face; we do not rely on it.)
//
// Timing: std::chrono::steady_clock, one thread (no TBB: CGAL's Parallel_tag is neither
// asked for nor compiled in), best of R repeats (the repeat with the smallest total).
// seed_seconds includes building the metric (per-face normals and areas) and the VSA object;
// total_seconds = seed_seconds + iterate_seconds. Reading the file is not timed. Every
// repeat starts from the same std::srand(S), so every repeat gives the same labels (checked).
// A warning goes to stderr when the best repeat's wall-clock time exceeds its CPU time by
// more than 10%: the process then waited for a core, and the figure is not to be trusted.
//
// Output: one CSV line on stdout (with --header, a header line first):
//   mesh,faces,k,k_obtained,seeding,iterations,seed_seconds,iterate_seconds,total_seconds,
//   energy_l21,cgal_error
// cgal_error is CGAL's own total error (compute_total_error) in the chosen metric; for l21
// it must agree with energy_l21 to rounding, which is checked.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_approximation/L21_metric_plane_proxy.h>
#include <CGAL/Surface_mesh_approximation/L2_metric_plane_proxy.h>
#include <CGAL/Variational_shape_approximation.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
using VertexPointMap = boost::property_map<Mesh, boost::vertex_point_t>::type;
namespace VSA = CGAL::Surface_mesh_approximation;

// --- The OFF file ---------------------------------------------------------------------

struct OffMesh {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<std::uint32_t, 3>> faces;
};

[[noreturn]] void Fail(const std::string& message) {
  std::cerr << "cgal_vsa: " << message << "\n";
  std::exit(1);
}

// Reads the next line that holds something other than a comment; false at end of file.
bool NextDataLine(std::istream& in, std::string& line, long& line_number) {
  while (std::getline(in, line)) {
    ++line_number;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    if (line.find_first_not_of(" \t\r") != std::string::npos) return true;
  }
  return false;
}

// Reads an ASCII OFF file of triangles (vertex colours or face colours after the indices
// are ignored). Faces keep the file's order.
OffMesh ReadOff(const std::string& path) {
  std::ifstream in(path);
  if (!in) Fail("cannot open " + path);
  std::string line;
  long line_number = 0;
  if (!NextDataLine(in, line, line_number)) Fail(path + ": empty file");
  std::istringstream header(line);
  std::string keyword;
  header >> keyword;
  if (keyword.size() < 3 || keyword.compare(keyword.size() - 3, 3, "OFF") != 0) {
    Fail(path + ": not an OFF file (first keyword '" + keyword + "')");
  }
  long num_vertices = -1, num_faces = -1;
  if (!(header >> num_vertices >> num_faces)) {
    if (!NextDataLine(in, line, line_number)) Fail(path + ": no counts line");
    std::istringstream counts(line);
    if (!(counts >> num_vertices >> num_faces)) Fail(path + ": bad counts line");
  }
  if (num_vertices < 0 || num_faces < 0 ||
      num_vertices > std::numeric_limits<std::uint32_t>::max()) {
    Fail(path + ": bad counts");
  }
  OffMesh mesh;
  mesh.points.resize(num_vertices);
  for (auto& p : mesh.points) {
    if (!NextDataLine(in, line, line_number)) Fail(path + ": file ends among the vertices");
    std::istringstream fields(line);
    if (!(fields >> p[0] >> p[1] >> p[2]) || !std::isfinite(p[0]) || !std::isfinite(p[1]) ||
        !std::isfinite(p[2])) {
      Fail(path + ":" + std::to_string(line_number) + ": bad vertex");
    }
  }
  mesh.faces.resize(num_faces);
  for (auto& f : mesh.faces) {
    if (!NextDataLine(in, line, line_number)) Fail(path + ": file ends among the faces");
    std::istringstream fields(line);
    long corners = 0;
    long v[3];
    if (!(fields >> corners) || corners != 3 || !(fields >> v[0] >> v[1] >> v[2])) {
      Fail(path + ":" + std::to_string(line_number) + ": not a triangle");
    }
    for (int c = 0; c < 3; ++c) {
      if (v[c] < 0 || v[c] >= num_vertices) {
        Fail(path + ":" + std::to_string(line_number) + ": vertex index out of range");
      }
      f[c] = static_cast<std::uint32_t>(v[c]);
    }
  }
  return mesh;
}

// Builds the Surface_mesh in file order and checks that face i is the file's face i.
Mesh BuildSurfaceMesh(const OffMesh& off) {
  Mesh mesh;
  mesh.reserve(off.points.size(), off.faces.size() * 3 / 2 + 3, off.faces.size());
  for (const auto& p : off.points) mesh.add_vertex(Point(p[0], p[1], p[2]));
  for (size_t i = 0; i < off.faces.size(); ++i) {
    const auto& f = off.faces[i];
    const Mesh::Face_index face =
        mesh.add_face(Mesh::Vertex_index(f[0]), Mesh::Vertex_index(f[1]), Mesh::Vertex_index(f[2]));
    if (face == Mesh::null_face()) {
      Fail("face " + std::to_string(i) + " cannot be added (non-manifold or degenerate)");
    }
    if (static_cast<size_t>(face.idx()) != i)
      Fail("Surface_mesh renumbered face " + std::to_string(i));
  }
  // The check the labels rely on: Surface_mesh face i has the file's triangle i.
  if (mesh.number_of_faces() != off.faces.size() || mesh.has_garbage()) {
    Fail("Surface_mesh face count differs from the file's");
  }
  for (Mesh::Face_index face : mesh.faces()) {
    const auto& expected = off.faces[face.idx()];
    std::array<std::uint32_t, 3> got{};
    int n = 0;
    for (Mesh::Vertex_index v : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) {
      if (n == 3) Fail("face " + std::to_string(face.idx()) + " is not a triangle");
      got[n++] = static_cast<std::uint32_t>(v.idx());
    }
    bool rotation = false;
    for (int r = 0; r < 3; ++r) {
      rotation |= got[0] == expected[r] && got[1] == expected[(r + 1) % 3] &&
                  got[2] == expected[(r + 2) % 3];
    }
    if (n != 3 || !rotation) Fail("face " + std::to_string(face.idx()) + " is not the file's");
  }
  return mesh;
}

// --- Our L2,1 energy ------------------------------------------------------------------

// The definition, in two passes: the clusters' normalised area-weighted normals, then the
// sum of A_j ||n_j - N_i||^2. Areas and normals as mlclust computes them
// (core/face_measures.cc): cross = (b - a) x (c - a), A = |cross| / 2, n = cross / |cross|.
double L21Energy(const OffMesh& off, const std::vector<std::size_t>& labels, size_t k) {
  const size_t n = off.faces.size();
  std::vector<double> area(n);
  std::vector<std::array<double, 3>> normal(n);
  for (size_t j = 0; j < n; ++j) {
    const auto& a = off.points[off.faces[j][0]];
    const auto& b = off.points[off.faces[j][1]];
    const auto& c = off.points[off.faces[j][2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double cross[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                             u[0] * v[1] - u[1] * v[0]};
    const double twice_area =
        std::sqrt(cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]);
    area[j] = 0.5 * twice_area;
    for (int d = 0; d < 3; ++d) normal[j][d] = twice_area > 0 ? cross[d] / twice_area : 0.0;
  }
  std::vector<std::array<double, 3>> mean(k, {0.0, 0.0, 0.0});
  for (size_t j = 0; j < n; ++j) {
    for (int d = 0; d < 3; ++d) mean[labels[j]][d] += area[j] * normal[j][d];
  }
  for (auto& m : mean) {
    const double length = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    if (length > 0) {
      for (double& x : m) x /= length;
    }
  }
  double energy = 0;
  for (size_t j = 0; j < n; ++j) {
    const auto& m = mean[labels[j]];
    double squared = 0;
    for (int d = 0; d < 3; ++d) squared += (normal[j][d] - m[d]) * (normal[j][d] - m[d]);
    energy += area[j] * squared;
  }
  return energy;
}

// --- One VSA run ----------------------------------------------------------------------

struct Options {
  std::string mesh_path;
  size_t k = 0;
  std::string seeding = "hierarchical";
  size_t iterations = 30;
  size_t relaxations = 5;
  std::string metric = "l21";
  std::string labels_path;
  unsigned seed = 1;
  int repeats = 3;
  bool header = false;
};

struct RunResult {
  double seed_seconds = 0;
  double iterate_seconds = 0;
  double total_seconds() const { return seed_seconds + iterate_seconds; }
  double cpu_seconds = 0;  // the process's CPU time over the same span
  size_t k_obtained = 0;
  double cgal_error = 0;
  std::vector<std::size_t> labels;  // face -> proxy, in the file's face order
};

using Clock = std::chrono::steady_clock;
double SecondsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}
double ProcessCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

template <typename Metric>
RunResult RunOnce(Mesh& mesh, const Options& options, VSA::Seeding_method method) {
  using Approximation = CGAL::Variational_shape_approximation<Mesh, VertexPointMap, Metric>;
  const VertexPointMap vpm = get(boost::vertex_point, mesh);
  RunResult result;
  std::srand(options.seed);
  const double cpu_start = ProcessCpuSeconds();
  const Clock::time_point start = Clock::now();
  const Metric metric(mesh, vpm);
  Approximation approximation(mesh, vpm, metric);
  approximation.initialize_seeds(CGAL::parameters::seeding_method(method)
                                     .max_number_of_proxies(options.k)
                                     .number_of_relaxations(options.relaxations));
  const Clock::time_point seeded = Clock::now();
  result.cgal_error = CGAL::to_double(approximation.run(options.iterations));
  const Clock::time_point done = Clock::now();
  result.cpu_seconds = ProcessCpuSeconds() - cpu_start;
  result.seed_seconds = SecondsBetween(start, seeded);
  result.iterate_seconds = SecondsBetween(seeded, done);
  result.k_obtained = approximation.number_of_proxies();

  // The labels, outside the timing.
  auto proxy_of = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:cgal_vsa_proxy").first;
  approximation.proxy_map(proxy_of);
  result.labels.resize(mesh.number_of_faces());
  for (Mesh::Face_index face : mesh.faces()) result.labels[face.idx()] = proxy_of[face];
  mesh.remove_property_map(proxy_of);
  return result;
}

[[noreturn]] void Usage(const std::string& problem) {
  if (!problem.empty()) std::cerr << "cgal_vsa: " << problem << "\n";
  std::cerr << "usage: cgal_vsa MESH.off --k K [--seeding random|incremental|hierarchical]\n"
               "         [--iterations N] [--relaxations R] [--metric l21|l2] [--labels OUT]\n"
               "         [--seed S] [--repeats R] [--header]\n";
  std::exit(2);
}

unsigned long ParseCount(const std::string& flag, const char* text) {
  char* end = nullptr;
  errno = 0;
  const unsigned long value = std::strtoul(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || text[0] == '-') {
    Usage("bad value '" + std::string(text) + "' for " + flag);
  }
  return value;
}

Options ParseOptions(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) Usage(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--k") {
      options.k = ParseCount(arg, value());
    } else if (arg == "--seeding") {
      options.seeding = value();
    } else if (arg == "--iterations") {
      options.iterations = ParseCount(arg, value());
    } else if (arg == "--relaxations") {
      options.relaxations = ParseCount(arg, value());
    } else if (arg == "--metric") {
      options.metric = value();
    } else if (arg == "--labels") {
      options.labels_path = value();
    } else if (arg == "--seed") {
      options.seed = static_cast<unsigned>(ParseCount(arg, value()));
    } else if (arg == "--repeats") {
      options.repeats = static_cast<int>(ParseCount(arg, value()));
    } else if (arg == "--header") {
      options.header = true;
    } else if (arg == "-h" || arg == "--help") {
      Usage("");
    } else if (!arg.empty() && arg[0] == '-') {
      Usage("unknown option " + arg);
    } else if (options.mesh_path.empty()) {
      options.mesh_path = arg;
    } else {
      Usage("more than one mesh");
    }
  }
  if (options.mesh_path.empty()) Usage("no mesh");
  if (options.k == 0) Usage("--k K (K >= 1) is required");
  if (options.repeats < 1) Usage("--repeats must be at least 1");
  if (options.seeding != "random" && options.seeding != "incremental" &&
      options.seeding != "hierarchical") {
    Usage("unknown seeding '" + options.seeding + "'");
  }
  if (options.metric != "l21" && options.metric != "l2") {
    Usage("unknown metric '" + options.metric + "'");
  }
  return options;
}

std::string MeshName(const std::string& path) {
  std::string name = path.substr(path.find_last_of('/') + 1);
  const size_t dot = name.rfind('.');
  if (dot != std::string::npos && dot > 0) name.resize(dot);
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  const Options options = ParseOptions(argc, argv);
  const OffMesh off = ReadOff(options.mesh_path);
  Mesh mesh = BuildSurfaceMesh(off);
  const size_t num_faces = off.faces.size();
  if (num_faces == 0) Fail("the mesh has no faces");
  const VSA::Seeding_method method = options.seeding == "random"        ? VSA::RANDOM
                                     : options.seeding == "incremental" ? VSA::INCREMENTAL
                                                                        : VSA::HIERARCHICAL;
  if (options.k >= num_faces / 3) {
    std::cerr << "cgal_vsa: K = " << options.k << " >= faces / 3 = " << num_faces / 3
              << ": CGAL seeds at most faces / 3 proxies, stopping at an error drop of 0.1\n";
  }

  RunResult best;
  for (int r = 0; r < options.repeats; ++r) {
    RunResult run = options.metric == "l21"
                        ? RunOnce<VSA::L21_metric_plane_proxy<Mesh, VertexPointMap, Kernel>>(
                              mesh, options, method)
                        : RunOnce<VSA::L2_metric_plane_proxy<Mesh, VertexPointMap, Kernel>>(
                              mesh, options, method);
    std::cerr << "cgal_vsa: repeat " << r + 1 << "/" << options.repeats << ": seeding "
              << run.seed_seconds << " s, " << options.iterations << " iterations "
              << run.iterate_seconds << " s, total " << run.total_seconds() << " s (CPU "
              << run.cpu_seconds << " s), " << run.k_obtained << " proxies\n";
    if (r > 0 && (run.labels != best.labels || run.k_obtained != best.k_obtained)) {
      Fail("repeat " + std::to_string(r + 1) + " gave other labels than repeat 1");
    }
    if (r == 0 || run.total_seconds() < best.total_seconds()) best = std::move(run);
  }

  // Wall time well above CPU time means the process waited for a core: other load.
  if (best.total_seconds() > 1.1 * best.cpu_seconds + 0.005) {
    std::cerr << "cgal_vsa: warning: disturbed timing: " << best.total_seconds()
              << " s wall-clock for " << best.cpu_seconds << " s CPU (other load?)\n";
  }
  for (std::size_t label : best.labels) {
    if (label >= best.k_obtained) Fail("a face has no proxy");
  }
  const double energy = L21Energy(off, best.labels, best.k_obtained);
  if (options.metric == "l21" &&
      std::abs(energy - best.cgal_error) > 1e-9 * std::max(1.0, std::abs(energy))) {
    std::cerr << "cgal_vsa: warning: our L2,1 energy " << energy << " differs from CGAL's "
              << best.cgal_error << "\n";
  }

  if (!options.labels_path.empty()) {
    std::ofstream out(options.labels_path);
    for (std::size_t label : best.labels) out << label << '\n';
    if (!out.flush()) Fail("cannot write " + options.labels_path);
  }

  if (options.header) {
    std::printf(
        "mesh,faces,k,k_obtained,seeding,iterations,seed_seconds,iterate_seconds,"
        "total_seconds,energy_l21,cgal_error\n");
  }
  std::printf("%s,%zu,%zu,%zu,%s,%zu,%.6f,%.6f,%.6f,%.9g,%.9g\n",
              MeshName(options.mesh_path).c_str(), num_faces, options.k, best.k_obtained,
              options.seeding.c_str(), options.iterations, best.seed_seconds, best.iterate_seconds,
              best.total_seconds(), energy, best.cgal_error);
  return 0;
}

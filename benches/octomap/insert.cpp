// OctoMap's side of the side-by-side benchmark: read the rays sigmap exported
// (`sigmap map ... --export-rays FILE`), insert every scan with
// insertPointCloud at the given resolution on one core, print the rate, and
// write the tree so the two maps can be compared. With `discretize`, OctoMap's
// discretized insertion (insertPointCloud(..., discretize = true)), which
// `sigmap map --method ray_update_discrete` builds.
//
// Build: g++ -O2 -std=c++17 insert.cpp -o insert -loctomap -loctomath
// Run:   ./insert RAYS_FILE RESOLUTION [OUT.ot|-] [discretize]
#include <octomap/octomap.h>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <vector>

struct Scan {
  octomap::point3d origin;
  octomap::Pointcloud cloud;
};

template <typename T> static bool get(std::ifstream& in, T& v) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(&v), sizeof(T)));
}

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s RAYS_FILE RESOLUTION [OUT.ot|-] [discretize]\n", argv[0]);
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  char magic[12];
  if (!in.read(magic, 12) || std::memcmp(magic, "SIGMAPRAYS1\n", 12) != 0) {
    std::fprintf(stderr, "%s: not a sigmap ray file\n", argv[1]);
    return 2;
  }
  float max_range = 0;
  uint32_t scans = 0;
  get(in, max_range);
  get(in, scans);
  std::vector<Scan> data(scans);
  size_t rays = 0;
  for (auto& scan : data) {
    float o[3];
    uint32_t n = 0;
    if (!get(in, o) || !get(in, n)) { std::fprintf(stderr, "truncated file\n"); return 2; }
    scan.origin = octomap::point3d(o[0], o[1], o[2]);
    scan.cloud.reserve(n);
    for (uint32_t i = 0; i < n; ++i) {
      float p[3];
      if (!get(in, p)) { std::fprintf(stderr, "truncated file\n"); return 2; }
      scan.cloud.push_back(p[0], p[1], p[2]);
    }
    rays += n;
  }
  const bool discretize = argc > 4 && std::strcmp(argv[4], "discretize") == 0;
  if (argc > 4 && !discretize) {
    std::fprintf(stderr, "%s: the fourth argument can only be 'discretize'\n", argv[4]);
    return 2;
  }
  octomap::OcTree tree(std::atof(argv[2]));
  auto start = std::chrono::steady_clock::now();
  for (auto& scan : data) tree.insertPointCloud(scan.cloud, scan.origin, max_range, false, discretize);
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  size_t inner = 0, leaves = tree.getNumLeafNodes(), nodes = tree.size();
  inner = nodes - leaves;
  std::printf("octomap rays %zu seconds %.6f rays_per_s %.1f nodes %zu leaves %zu bytes %zu\n", rays, seconds,
              rays / seconds, nodes, leaves, tree.memoryUsage());
  (void)inner;
  if (argc > 3 && std::strcmp(argv[3], "-") != 0) tree.write(argv[3]);
  return 0;
}

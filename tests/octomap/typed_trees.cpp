// OctoMap's other occupancy trees, for tests/octomap_tools.rs: one scan of a
// bumpy wall inserted into an OcTreeStamped and a ColorOcTree (every leaf
// given its own colour, the inner nodes' colours averaged), each written as
// .ot and .bt, with its leaves listed as OctoMap's own iterator gives them:
// `x y z depth log-odds-bits` (the node's key, its depth, the f32 bits).
// With `list FILE.ot`, reads a ColorOcTree file (`sigmap score --errors
// FILE.ot`) with OctoMap's reader and lists its leaves, each with its colour:
// `x y z depth log-odds-bits r g b`.
//
// Build: g++ -O2 -std=c++17 typed_trees.cpp -o typed_trees -loctomap -loctomath
// Run:   ./typed_trees RESOLUTION OUTDIR
//        ./typed_trees list FILE.ot
#include <octomap/ColorOcTree.h>
#include <octomap/OcTreeStamped.h>
#include <octomap/octomap.h>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>

static octomap::Pointcloud wall() {
  octomap::Pointcloud cloud;
  for (int i = -60; i <= 60; ++i)
    for (int j = -40; j <= 40; ++j) {
      double y = 0.01 * i, z = 0.01 * j;
      cloud.push_back(1.0 + 0.05 * std::sin(7.0 * y) * std::cos(5.0 * z), y, z);
    }
  return cloud;
}

// Each leaf as `x y z depth log-odds-bits`, then what `extra` adds.
template <class Tree, class Extra>
static void list(const Tree& tree, std::ostream& out, Extra extra) {
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    float value = it->getLogOdds();
    uint32_t bits;
    std::memcpy(&bits, &value, 4);
    const octomap::OcTreeKey key = it.getKey();
    out << key[0] << ' ' << key[1] << ' ' << key[2] << ' ' << it.getDepth() << ' ' << bits;
    extra(*it, out);
    out << '\n';
  }
}

template <class Tree> static void leaves(const Tree& tree, const std::string& path) {
  std::ofstream out(path);
  list(tree, out, [](const auto&, std::ostream&) {});
}

// The tree as .ot and .bt (writeBinaryConst: the tree as it is, where
// writeBinary would first turn it into its maximum-likelihood tree), and its
// leaves.
template <class Tree> static void write(const Tree& tree, const std::string& stem) {
  tree.write(stem + ".ot");
  tree.writeBinaryConst(stem + ".bt");
  leaves(tree, stem + ".leaves");
}

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s RESOLUTION OUTDIR | %s list FILE.ot\n", argv[0], argv[0]);
    return 2;
  }
  if (std::strcmp(argv[1], "list") == 0) {
    octomap::AbstractOcTree* read = octomap::AbstractOcTree::read(argv[2]);
    auto* tree = dynamic_cast<octomap::ColorOcTree*>(read);
    if (tree == nullptr) {
      std::fprintf(stderr, "%s: not a ColorOcTree\n", argv[2]);
      return 1;
    }
    list(*tree, std::cout, [](const octomap::ColorOcTreeNode& node, std::ostream& out) {
      const auto colour = node.getColor();
      out << ' ' << int(colour.r) << ' ' << int(colour.g) << ' ' << int(colour.b);
    });
    delete read;
    return 0;
  }
  const double resolution = std::atof(argv[1]);
  const std::string dir = argv[2];
  octomap::OcTreeStamped stamped(resolution);
  stamped.insertPointCloud(wall(), octomap::point3d(0, 0, 0), 3.0);
  write(stamped, dir + "/stamped");
  octomap::ColorOcTree colour(resolution);
  colour.insertPointCloud(wall(), octomap::point3d(0, 0, 0), 3.0);
  for (auto it = colour.begin_leafs(); it != colour.end_leafs(); ++it) {
    const octomap::OcTreeKey key = it.getKey();
    it->setColor(key[0] & 255, key[1] & 255, (key[2] + it.getDepth()) & 255);
  }
  colour.updateInnerOccupancy();
  write(colour, dir + "/colour");
  return 0;
}

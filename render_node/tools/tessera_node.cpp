// tessera-node: one render node of the wall (render_node/). Parses the command line
// and wires a cluster link to render_node::RenderNode (render_node/render_node.h). Inside one MPI
// job, started by mpirun after the master:
//   mpirun -np 1 tessera-master --wall W.json --scene S.json ... : -np K tessera-node [--headless]
// or over ZeroMQ, one per tile, on any host, in any order, at any time:
//   tessera-node --master tcp://HOST:7400 [--tile NAME] [--headless] [--wait-master S]
#include <CLI/CLI.hpp>

#include <tessera/core/cli.h>

#include <cstdio>
#include <memory>

#include <tessera/render_node/render_node.h>
#include <tessera/sync/mpi_link.h>
#include <tessera/sync/zmq_link.h>

namespace {

int run(int argc, char** argv) {
  using namespace tessera;
  render_node::NodeOptions o;
  std::string master;
  double timeout_s = 120.0;
  CLI::App app{
      "tessera-node: one render node of the wall; joins tessera-master over ZeroMQ (--master) "
      "or inside an mpirun job"};
  app.add_flag("--headless", o.headless, "Render off-screen (EGL) instead of in a window");
  app.add_option("--master", master,
                 "ZeroMQ: the master's endpoint (tcp://HOST:7400); without it, the node is a "
                 "rank of an mpirun job");
  app.add_option("--tile", o.tile, "The wall tile to drive (default: the first free one)");
  app.add_option("--join-timeout", o.join_timeout_s,
                 "ZeroMQ: seconds to wait for the master's answer to the join")
      ->check(cli::finiteRange(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--wait-master", o.wait_master_s,
                 "ZeroMQ: after losing the master, wait this many seconds for a new one at the "
                 "same endpoint (0: exit at once)")
      ->check(cli::finiteRange(0.0, 86400.0))
      ->capture_default_str();
  app.add_option("--master-timeout", o.master_timeout_s,
                 "Seconds without any message from the master before the node gives up")
      ->check(cli::finiteRange(1.0, 86400.0))
      ->capture_default_str();
  app.add_option("--timeout", timeout_s,
                 "MPI: seconds to wait for the master's first message before aborting the job "
                 "(exit 17); after it, twice the larger of this and the master's --timeout")
      ->check(cli::finiteRange(0.1, 86400.0))
      ->capture_default_str();

  bool want_mpi = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--master" || a.rfind("--master=", 0) == 0) want_mpi = false;
    if (a == "--help" || a == "-h") want_mpi = false;
  }
  if (!want_mpi) {
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      return cli::exitCode(app, e, "tessera-node");
    }
    try {
      sync::ZmqNodeLink link(master);
      return render_node::RenderNode(link, o).run();
    } catch (const sync::LinkError& e) {
      std::fprintf(stderr, "tessera-node: --master %s: %s\n", master.c_str(), e.what());
      return cluster::NODE_MASTER_LOST;
    }
  }
  // MPI may add its own arguments; ours are parsed after MPI_Init removed them.
  std::unique_ptr<sync::MpiTransport> mpi;
  try {
    mpi = std::make_unique<sync::MpiTransport>(&argc, &argv, "tessera-node", timeout_s);
  } catch (const sync::TransportError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (mpi->rank() == 0) return cli::exitCode(app, e, "tessera-node");
    mpi->abort(2, std::string("bad command line: ") + e.what());
  }
  mpi->setTimeout(timeout_s);
  if (mpi->rank() == 0) {
    mpi->abort(2,
               "tessera-node is rank 0, where tessera-master belongs: start "
               "`mpirun -np 1 tessera-master ... : -np K tessera-node`, or give --master "
               "tcp://HOST:PORT for ZeroMQ");
  }
  sync::MpiNodeLink link(*mpi);
  const int own = render_node::RenderNode(link, o).run();
  // One MPI job, one exit code: every rank exits with the master's (its quit), so mpirun's code
  // does not depend on which rank ends first. This node's own failure is in the master's message.
  return link.quitCode().value_or(own);
}

}  // namespace

int main(int argc, char** argv) {
  return tessera::cli::runMain(
      "tessera-node", [&] { return run(argc, argv); }, tessera::cluster::NODE_INTERNAL);
}

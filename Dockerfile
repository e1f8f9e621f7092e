# syntax=docker/dockerfile:1
# gi-server on Debian 12: a builder stage with the -dev packages, a runtime
# stage with only the shared libraries. Build and run:
#   docker build -t gi-server .
#   docker run --rm -p 8080:8080 gi-server          # the HTTP server, city only
#   docker run --rm -v "$PWD/configs/docker.ini:/etc/gi-server/gi-server.ini:ro" -p 8080:8080 gi-server
#   gi-client --server http://127.0.0.1:8080 health # from the host
#   docker run --rm -v "$PWD/out:/out" gi-server gi-bake city --exr /out/city.exr --vdb /out/city.vdb
# The image holds configs/docker.ini as the default config; mount your own
# over /etc/gi-server/gi-server.ini (scene files it names must be mounted too;
# its relative paths are relative to the config file). A mounted output
# folder must be writable by uid 10001.

# --- builder -------------------------------------------------------------------
FROM debian:bookworm-slim AS build
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /src
# The package list lives in one place: the same script `make` runs.
COPY scripts/install-deps.sh scripts/install-deps.sh
RUN sh scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
# Only the sources: no local build/ or out/ folders leak in.
COPY CMakeLists.txt Makefile ./
COPY cmake cmake
COPY core core
COPY proto proto
COPY server server
COPY tools tools
COPY tests tests
COPY configs configs
RUN cmake -S . -B build -DCMAKE_BUILD_TYPE=Release \
 && cmake --build build -j"$(nproc)"
# Optional: docker build --build-arg RUN_TESTS=1 . runs the suite in the image
# (tests that need ../shared/scenes skip).
ARG RUN_TESTS=0
RUN if [ "$RUN_TESTS" = 1 ]; then cd build && ctest --output-on-failure -j"$(nproc)"; fi
# The install step a host uses (make install): the commands in /opt/gi/bin,
# libgi (shared and static), its headers, gi.pc and the CMake package.
RUN cmake --install build --prefix /opt/gi

# --- runtime -------------------------------------------------------------------
FROM debian:bookworm-slim
ENV DEBIAN_FRONTEND=noninteractive
# Runtime libraries of gicore and the tools (their own dependencies, such as
# libimath, libblosc1 and libboost-iostreams, come along); libmicrohttpd12
# and libinih1 for gi-server, libcurl4 for gi-client (the health check).
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libembree3-3 libopenexr-3-1-30 libopenvdb10.0 libassimp5 libtbb12 \
      libpng16-16 libjpeg62-turbo \
      libjansson4 libmicrohttpd12 libinih1 libcurl4 ca-certificates \
 && rm -rf /var/lib/apt/lists/*
RUN useradd --system --uid 10001 --create-home --home-dir /home/gi --shell /usr/sbin/nologin gi
COPY --from=build /opt/gi/ /opt/gi/
ENV PATH=/opt/gi/bin:$PATH
# The default config (root-owned, read-only for gi); a mount replaces it.
COPY configs/docker.ini /etc/gi-server/gi-server.ini
USER gi
WORKDIR /home/gi
EXPOSE 8080
# /v1/health needs no token. The city takes a few seconds to load: the
# start period keeps those from counting as failures.
HEALTHCHECK --interval=30s --timeout=5s --start-period=60s --retries=3 \
  CMD gi-client --server http://127.0.0.1:8080 -q health || exit 1
CMD ["gi-server", "--config", "/etc/gi-server/gi-server.ini"]

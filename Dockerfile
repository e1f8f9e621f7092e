# syntax=docker/dockerfile:1
# gi-server on Debian 12: a builder stage with the -dev packages, a runtime
# stage with only the shared libraries. Build and run:
#   docker build -t gi-server .
#   docker run --rm gi-server                        # gi-bake city --json
#   docker run --rm -v "$PWD/out:/out" gi-server gi-bake city --exr /out/city.exr --vdb /out/city.vdb
# (the mounted folder must be writable by uid 10001).

# --- builder -------------------------------------------------------------------
FROM debian:bookworm-slim AS build
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /src
# The package list lives in one place: the same script `make` runs.
COPY scripts/install-deps.sh scripts/install-deps.sh
RUN sh scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
# Only the sources: no local build/ or out/ folders leak in. Add server/,
# proto/ and configs/ here when they hold files.
COPY CMakeLists.txt Makefile ./
COPY core core
COPY tools tools
COPY tests tests
RUN cmake -S . -B build -DCMAKE_BUILD_TYPE=Release \
 && cmake --build build -j"$(nproc)"
# Optional: docker build --build-arg RUN_TESTS=1 . runs the suite in the image
# (tests that need ../shared/scenes skip).
ARG RUN_TESTS=0
RUN if [ "$RUN_TESTS" = 1 ]; then cd build && ctest --output-on-failure -j"$(nproc)"; fi

# --- runtime -------------------------------------------------------------------
FROM debian:bookworm-slim
ENV DEBIAN_FRONTEND=noninteractive
# Runtime libraries of gicore and the tools (their own dependencies, such as
# libimath, libblosc1 and libboost-iostreams, come along). libmicrohttpd12
# and libcurl4 are for the server and client that land next.
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libembree3-3 libopenexr-3-1-30 libopenvdb10.0 libassimp5 libtbb12 \
      libpng16-16 libjpeg62-turbo \
      libjansson4 libmicrohttpd12 libcurl4 ca-certificates \
 && rm -rf /var/lib/apt/lists/*
RUN useradd --system --uid 10001 --create-home --home-dir /home/gi --shell /usr/sbin/nologin gi
COPY --from=build /src/build/bin/ /usr/local/bin/
USER gi
WORKDIR /home/gi
# HEALTHCHECK: comes with the HTTP server (GET /v1/health); a batch command
# has nothing to probe.
CMD ["gi-bake", "city", "--json"]

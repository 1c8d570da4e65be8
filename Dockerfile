# rsf-stability image: the API (`rsf api`) or a worker (`rsf worker`), same image.
# rsfcore's kernels are compiled at build time into /app/.numba_cache, so a container
# starts in about a second (numba recompiles only on a CPU of a different family).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    RSF_DATA_DIR=/data NUMBA_CACHE_DIR=/app/.numba_cache

WORKDIR /app
COPY pyproject.toml README.md ./
COPY rsfcore ./rsfcore
COPY rsfapp ./rsfapp
COPY rsfplots ./rsfplots
COPY rsfcli ./rsfcli
COPY service ./service
COPY worker ./worker
COPY rsfclient ./rsfclient
# the service, CLI, figures and fits (extra `all`), the PostgreSQL driver (extra
# `postgres`), then
# the compiled kernels
RUN pip install ".[all,postgres]" \
    && python -c "from rsfapp.warmup import warm_up; warm_up()" \
    && test -n "$(ls -A /app/.numba_cache)" \
    && useradd --create-home --uid 10001 rsf \
    && mkdir -p /data && chown -R rsf:rsf /data /app/.numba_cache
USER rsf
EXPOSE 8000

# /health is 503 while the database or the broker is down or the database is damaged;
# with API keys on it needs a key (RSF_API_KEY, as docker-compose sets it)
HEALTHCHECK --interval=15s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import os,sys,urllib.request as u; k=os.environ.get('RSF_API_KEY'); h={'Authorization': 'Bearer '+k} if k else {}; sys.exit(u.urlopen(u.Request('http://127.0.0.1:8000/health', headers=h), timeout=4).status != 200)"

CMD ["rsf", "api", "--host", "0.0.0.0", "--port", "8000"]

# rsf-stability service image: the API (uvicorn) or a Celery worker, same image.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    RSF_DATA_DIR=/data NUMBA_CACHE_DIR=/tmp/numba-cache

WORKDIR /app
COPY pyproject.toml README.md ./
COPY rsfcore ./rsfcore
COPY rsfplots ./rsfplots
COPY rsfcli ./rsfcli
COPY service ./service
COPY worker ./worker
RUN pip install . \
    && useradd --create-home --uid 10001 rsf \
    && mkdir -p /data && chown rsf:rsf /data
USER rsf
VOLUME ["/data"]
EXPOSE 8000

HEALTHCHECK --interval=15s --timeout=5s --start-period=60s --retries=3 \
    CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/health', timeout=4).status != 200)"

CMD ["uvicorn", "service.app:app", "--host", "0.0.0.0", "--port", "8000"]
